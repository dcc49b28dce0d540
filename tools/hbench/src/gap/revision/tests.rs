//! The end of a run asked again: a contested step's rival, a clear step of a run far
//! above the floor, and the question widened by one recalibration.

use hbmodel::effects::Effect;

use super::*;
use crate::gap::blind::Setup;
use crate::gap::effects::{candidate, StepKind};
use crate::gap::fit::{fit, Target};
use crate::gap::hide::Kind;
use crate::gap::recalibrate;
use crate::gap::tests::record;
use crate::gap::variants::Simulator;
use crate::gap::{target_of, Scored};

/// A run whose first step took `taken` over `rival` (scores 100 and `rival_score`;
/// 99 is a hair, ln B 0.5, both paid), then recalibrated SV1's rated flow.
fn run_taking<'t>(
    target: &'t Target<'t>,
    names: &'t [String],
    known: &hbmodel::Params,
    taken: Effect,
    rival: Effect,
    rival_score: f64,
) -> Search<'t> {
    let mut s = Search::new(target, names, known, 0.15, false);
    let take = candidate(taken).expect("a candidate");
    let first = fit(target, known, &take, &[]);
    let scored = |name: &str, score: f64| Scored {
        effect: name.into(),
        gap: first.gap,
        score,
        parameters: Default::default(),
        on_bound: None,
    };
    let candidates = vec![
        scored(taken.name(), 100.0),
        scored(rival.name(), rival_score),
    ];
    let round = advice::Round {
        start: known.clone(),
        tau: 1.0,
        fits: vec![(100.0, first.clone())],
    };
    let step = step_of(&first, known, s.gap, candidates, 1000.0, None);
    s.take(step, round, &first);
    let flow = recalibrate::candidates(&s.model, 0.15, &[])
        .into_iter()
        .find(|c| c.name() == "sv1.rated_flow")
        .expect("the flow is open");
    let second = fit(target, &s.model, &flow, &s.carried);
    let round = advice::Round {
        start: s.model.clone(),
        tau: 1.0,
        fits: vec![(10.0, second.clone())],
    };
    let step = step_of(&second, &s.model, s.gap, Vec::new(), 1000.0, None);
    s.take(step, round, &second);
    s.verdict = "ended".into();
    s
}

/// A sensor delay hidden in +-10 mm steps. A run that took a valve lag at its first
/// step over the delay by a hair is asked again, names the delay clearly, and is
/// continued from it to a better end; a run that took the delay over the valve lag
/// stands. Taking a run back keeps what the step before it had.
#[test]
fn a_contested_step_is_asked_again_and_the_run_continued_from_a_clear_rival() {
    let s = Setup::new(Simulator::Rust, false, &[Effect::SensorDelay], 2);
    let records = [record(&s, Kind::Steps, 2)];
    let target = target_of(&records).expect("a target");
    let names = vec!["steps".to_string()];

    let wrong = run_taking(
        &target,
        &names,
        &s.known,
        Effect::ValveDynamics,
        Effect::SensorDelay,
        99.0,
    );
    assert!(advice::contested(&wrong.steps[0]).is_some());
    let back = wrong.before(1).expect("step 2 was taken");
    assert_eq!(back.steps.len(), 1);
    assert_eq!(back.carried.len() + 1, wrong.carried.len());
    assert!(back.recalibrated.is_empty());
    assert_eq!(back.model.to_toml(), wrong.rounds[1].start.to_toml());
    let r = reask(&wrong, 0.15, false).expect("the first step was contested");
    assert_eq!(r.report.step, 0);
    assert_eq!(r.report.recalibrate, ["sv1.rated_flow"]);
    assert_eq!(
        r.report.decision.winner.as_deref(),
        Some("sensor_delay"),
        "{:?}",
        r.report
    );
    assert!(r.report.revised, "{}", r.report.verdict);
    let kept = r.kept.expect("the continued run is kept");
    let first_added = kept
        .steps
        .iter()
        .find(|s| s.kind == StepKind::Add)
        .expect("an effect");
    assert_eq!(first_added.name, "sensor_delay");
    assert!(kept.gap < wrong.gap, "{} against {}", kept.gap, wrong.gap);
    let truth = s.drawn[0].1;
    assert!(
        (kept.model.sensors.delay / truth - 1.0).abs() < 0.1,
        "{} against {truth}",
        kept.model.sensors.delay
    );

    let right = run_taking(
        &target,
        &names,
        &s.known,
        Effect::SensorDelay,
        Effect::ValveDynamics,
        99.0,
    );
    let r = reask(&right, 0.15, false).expect("the first step was contested");
    assert!(
        !r.report.revised && r.kept.is_none(),
        "{}",
        r.report.verdict
    );
    assert!(r.report.continued.is_none());
}

/// A step taken clearly (ln B 10) is asked again only when the run ended far above
/// the noise floor, and only if its rival paid its price.
#[test]
fn a_clear_step_is_asked_again_only_when_the_run_ends_far_above_the_floor() {
    let s = Setup::new(Simulator::Rust, false, &[Effect::SensorDelay], 2);
    let records = [record(&s, Kind::Steps, 2)];
    let target = target_of(&records).expect("a target");
    let names = vec!["steps".to_string()];
    let mut run = run_taking(
        &target,
        &names,
        &s.known,
        Effect::ValveDynamics,
        Effect::SensorDelay,
        80.0,
    );
    assert!(advice::contested(&run.steps[0]).is_none());
    assert_eq!(advice::rival(&run.steps[0]), Some("sensor_delay"));

    run.gap = 0.9 * FAR_ABOVE_FLOOR_GAP;
    assert!(
        question(&run).is_none(),
        "a clear step of a run near the floor"
    );
    run.gap = 2.0 * FAR_ABOVE_FLOOR_GAP;
    let q = question(&run).expect("a run far above the floor");
    assert_eq!((q.k, q.rival.as_str()), (0, "sensor_delay"));
    assert_eq!(q.later, ["sv1.rated_flow"]);
    assert!(q.why.contains("far above"), "{}", q.why);
    assert!(q.earlier.steps.is_empty());

    // a rival that did not pay its price is no question
    run.steps[0].candidates[1].score = -1.0;
    assert!(advice::rival(&run.steps[0]).is_none());
    assert!(question(&run).is_none());
}

/// A question widened keeps the one extra recalibration whose best fit pays its
/// price (ln N_eff for the parameter), skips one that does not or whose ask failed,
/// never asks a parameter the set already has, and keeps the plain set when none pays
/// or when the plain question already cleared the rival.
#[test]
fn a_question_is_widened_only_by_a_recalibration_that_pays_its_price() {
    use std::cell::RefCell;
    let s = Setup::new(Simulator::Rust, false, &[Effect::SensorDelay], 2);
    let records = [record(&s, Kind::Steps, 2)];
    let target = target_of(&records).expect("a target");
    let names = vec!["steps".to_string()];
    let between = ["valve_dynamics".to_string(), "sensor_delay".to_string()];
    let plain = decision::ask(&s.known, &between, &[], &target, &names, 0.15, false)
        .expect("the plain question");
    let chi2 = plain.best_chi2();
    let effective = plain.decision.effective_samples;
    let singles = decision::single_recalibrations(&s.known, 0.15);
    let open = decision::open(&s.known, 0.15, &singles, &between);
    assert!(open.len() >= 4, "{open:?}");
    let (held, pays, cheap, fails) = (&open[0], &open[1], &open[2], &open[3]);

    // the set's last parameter decides its fit: `pays` halves the chi-square, `cheap`
    // gains half its price, `fails` cannot be asked, the others change nothing
    let asked = RefCell::new(Vec::<Vec<String>>::new());
    let fake = |gains: bool| {
        let (plain, asked) = (&plain, &asked);
        move |set: &[String]| -> Option<Asked> {
            asked.borrow_mut().push(set.to_vec());
            let last = set.last()?;
            let factor = if gains && last == pays {
                0.5
            } else if last == cheap {
                (-0.5 * effective.ln() / effective).exp()
            } else if last == fails {
                return None;
            } else {
                1.0
            };
            let mut a = plain.clone();
            a.fits.iter_mut().for_each(|f| f.chi2 = chi2 * factor);
            Some(a)
        }
    };

    // with `pays` gaining, its set is kept; without, half the price does not pay; a plain
    // question that already clears the rival is not widened (nothing asked)
    let widening = open.len() - 1;
    for (gains, cleared, kept, factor, calls_made) in [
        (true, false, Some(pays), 0.5, widening),
        (false, false, None, 1.0, widening),
        (true, true, None, 1.0, 0),
    ] {
        let ask = fake(gains);
        let (set, a) = widened(
            &s.known,
            &between,
            (vec![held.clone()], plain.clone()),
            0.15,
            &|_| cleared,
            &ask,
        );
        let expected: Vec<String> = [held].into_iter().chain(kept).cloned().collect();
        assert_eq!(set, expected, "gains: {gains}, cleared: {cleared}");
        assert!((a.best_chi2() / chi2 - factor).abs() < 1e-12);
        let calls = asked.take();
        assert_eq!(calls.len(), calls_made, "{calls:?}");
        assert!(calls
            .iter()
            .all(|c| c[0] == *held && c.len() == 2 && c[1] != *held));
    }
}
