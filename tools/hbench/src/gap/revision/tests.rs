//! The end of a run asked again: a contested step's rival, a clear step of a run far
//! above the floor or whose size the run moved, a recalibration every candidate pinned
//! to a bound held, and the question widened by one recalibration.

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
pub(super) fn run_taking<'t>(
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
        bounded: Vec::new(),
        trades: None,
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

/// A sensor delay hidden in the +-10 mm steps of the Rust bench (seed 2, no form error),
/// and their record.
pub(super) fn delay_on_steps() -> (Setup, [crate::gap::Record; 1]) {
    let s = Setup::new(Simulator::Rust, false, &[Effect::SensorDelay], 2);
    let records = [record(&s, Kind::Steps, 2)];
    (s, records)
}

/// A run that took a valve lag over the sensor delay by a hair (`run_taking`).
pub(super) fn lag_taken<'t>(
    target: &'t Target<'t>,
    names: &'t [String],
    known: &hbmodel::Params,
) -> Search<'t> {
    run_taking(
        target,
        names,
        known,
        Effect::ValveDynamics,
        Effect::SensorDelay,
        99.0,
    )
}

/// The fit of the recalibration `name` of the known model.
fn recalibration_fit(target: &Target, known: &hbmodel::Params, name: &str) -> crate::gap::fit::Fit {
    let c = recalibrate::candidates(known, 0.15, &[])
        .into_iter()
        .find(|c| c.name() == name)
        .expect("the recalibration is open");
    fit(target, known, &c, &[])
}

/// A sensor delay hidden in +-10 mm steps. A run that took a valve lag at its first
/// step over the delay by a hair is asked again, names the delay clearly, and is
/// continued from it to a better end; a run that took the delay over the valve lag
/// stands. Taking a run back keeps what the step before it had.
#[test]
fn a_contested_step_is_asked_again_and_the_run_continued_from_a_clear_rival() {
    let (s, records) = delay_on_steps();
    let target = target_of(&records).expect("a target");
    let names = vec!["steps".to_string()];

    let wrong = lag_taken(&target, &names, &s.known);
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

/// A step taken clearly (ln B 10) is asked again only when it added an effect and the
/// run ended far above the noise floor or moved its size by more than MOVED_BY, and
/// only if its rival paid its price; a contested one is asked however the run ended; a rival the run recalibrated anyway is stood in for
/// by the best effects of the step's round, and an effect the run added after a step
/// whose size it moved is asked beside the rival.
#[test]
fn a_clear_step_is_asked_again_only_when_the_run_ends_far_above_the_floor_or_moved_it() {
    let (s, records) = delay_on_steps();
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
    assert_eq!(
        (q.k, q.rivals.as_slice()),
        (0, ["sensor_delay".to_string()].as_slice())
    );
    assert_eq!(q.later, ["sv1.rated_flow"]);
    assert!(q.why.contains("far above"), "{}", q.why);
    assert!(q.earlier.steps.is_empty());

    // a rival that did not pay its price is no question
    let paid = run.steps[0].candidates[1].score;
    run.steps[0].candidates[1].score = -1.0;
    assert!(advice::rival(&run.steps[0]).is_none());
    assert!(question(&run).is_none());
    run.steps[0].candidates[1].score = paid;

    // near the floor, a step whose own first parameter the run moved by more than
    // MOVED_BY is asked, and the report says from what to what
    run.gap = 0.9 * FAR_ABOVE_FLOOR_GAP;
    let own = candidate(Effect::ValveDynamics)
        .expect("a candidate")
        .fitted[0]
        .path;
    let spec = hbmodel::params::param(own).expect("registered");
    let at_step = run.steps[0].parameters[own].as_f64().expect("fitted");
    for (factor, asked) in [(1.2, false), (1.3, true), (0.7, true)] {
        spec.set(&mut run.model, at_step * factor);
        let q = question(&run);
        assert_eq!(q.is_some(), asked, "moved by {factor}");
        if let Some(q) = q {
            assert_eq!(
                (q.k, q.rivals.as_slice()),
                (0, ["sensor_delay".to_string()].as_slice())
            );
            assert!(q.why.contains(&format!("moved its `{own}`")), "{}", q.why);
        }
    }
    // an effect the run added after the step is asked beside the rival when the step's
    // size moved (`movers`), if it was a candidate of the step's round
    let mut added = run.clone();
    let mut friction = added.steps[1].clone();
    friction.name = Effect::DryFriction.name().into();
    friction.kind = StepKind::Add;
    added.steps.push(friction);
    spec.set(&mut added.model, at_step * 1.3);
    let rivals = |run: &Search| question(run).map(|q| q.rivals);
    assert_eq!(rivals(&added), Some(vec!["sensor_delay".to_string()]));
    let effect_fit = |e: Effect| fit(&target, &s.known, &candidate(e).expect("a candidate"), &[]);
    added.rounds[0]
        .fits
        .push((-3.0, effect_fit(Effect::DryFriction)));
    assert_eq!(
        rivals(&added),
        Some(vec!["sensor_delay".to_string(), "dry_friction".to_string()])
    );
    // not when the step was asked for a run far above the floor with its size unmoved
    spec.set(&mut added.model, at_step);
    added.gap = 2.0 * FAR_ABOVE_FLOOR_GAP;
    assert_eq!(rivals(&added), Some(vec!["sensor_delay".to_string()]));

    // a recalibration step is not asked for its own parameter's moving
    spec.set(&mut run.model, at_step * 2.0);
    run.steps[0].kind = StepKind::Recalibrate;
    assert!(question(&run).is_none());

    // a rival the run recalibrated anyway is stood in for by the round's two best effects
    // that paid their price (`stand_ins`): asked against the recalibration with it
    // re-fitted beside each, the question would ask nothing; an effect that did not pay
    // stands in for nothing
    run.steps[0].kind = StepKind::Add;
    spec.set(&mut run.model, at_step);
    run.gap = 2.0 * FAR_ABOVE_FLOOR_GAP;
    // the rival becomes SV1's rated flow, which the run's second step re-fitted
    run.steps[0].candidates[1].effect = "sv1.rated_flow".into();
    if let Some(p) = run.steps[0].preference.as_mut() {
        p.runner_up = "sv1.rated_flow".into();
    }
    assert_eq!(advice::rival(&run.steps[0]), Some("sv1.rated_flow"));
    let flow = run.rounds[1].fits[0].1.clone();
    let fits = &mut run.rounds[0].fits;
    fits.push((99.0, flow));
    fits.push((40.0, effect_fit(Effect::DryFriction)));
    fits.push((-5.0, effect_fit(Effect::EntrainedAir)));
    fits.push((60.0, effect_fit(Effect::SensorDelay)));
    fits.push((30.0, effect_fit(Effect::InternalLeakage)));
    let q = question(&run).expect("a run far above the floor");
    assert_eq!(q.k, 0);
    assert_eq!(q.later, ["sv1.rated_flow"]);
    assert_eq!(q.rivals, ["sensor_delay", "dry_friction"], "{}", q.why);

    // in a run that ended far above the floor, the step's rival is asked
    // with the round's other effects that paid their price beside it (`stand_ins`)
    let rival_is = |run: &mut Search, name: &str| {
        run.steps[0].candidates[1].effect = name.into();
        if let Some(p) = run.steps[0].preference.as_mut() {
            p.runner_up = name.into();
        }
    };
    rival_is(&mut run, "sensor_delay");
    let q = question(&run).expect("a run far above the floor");
    assert_eq!(q.rivals, ["sensor_delay", "dry_friction"], "{}", q.why);
    rival_is(&mut run, "internal_leakage");
    let q = question(&run).expect("a run far above the floor");
    assert_eq!(
        q.rivals,
        ["internal_leakage", "sensor_delay", "dry_friction"],
        "{}",
        q.why
    );
    // a recalibration taken clearly is a question of values, not of what the model
    // lacks: a run far above the floor does not ask it, whether its rival adds an effect
    // or re-fits another recalibration; contested, it is asked either way
    run.steps[0].kind = StepKind::Recalibrate;
    assert!(question(&run).is_none(), "rival adds an effect");
    rival_is(&mut run, "sv1.null_bias");
    run.rounds[0]
        .fits
        .push((50.0, recalibration_fit(&target, &s.known, "sv1.null_bias")));
    assert_eq!(advice::rival(&run.steps[0]), Some("sv1.null_bias"));
    assert!(question(&run).is_none(), "rival re-fits a recalibration");
    let p = run.steps[0].preference.as_mut().expect("a preference");
    p.ln_bayes_factor = 0.5 * CLEAR_LN_BAYES;
    assert!(advice::contested(&run.steps[0]).is_some());
    let q = question(&run).expect("a contested step of a run far above the floor");
    assert_eq!((q.k, q.why.as_str()), (0, "contested"));
    let listed_three = listed(&["a".into(), "b".into(), "c".into()]);
    assert_eq!(listed_three, "`a`, `b` and `c`");
}

/// A question widened keeps the one extra recalibration whose best fit pays its
/// price (ln N_eff for the parameter), skips one that does not or whose ask failed,
/// never asks a parameter the set already has, and keeps the plain set when none pays
/// or when the plain question already cleared the rival.
#[test]
fn a_question_is_widened_only_by_a_recalibration_that_pays_its_price() {
    use std::cell::RefCell;
    let (s, between, plain) = delay_or_lag();
    let chi2 = plain.best_misfit().chi2();
    let effective = plain.decision.effective_samples();
    let singles = decision::single_recalibrations(&s.known, 0.15);
    let open = decision::open(&s.known, 0.15, &singles, &between);
    assert!(open.len() >= 5, "{open:?}");
    let (held, pays, cheap, fails, pinned) = (&open[0], &open[1], &open[2], &open[3], &open[4]);

    // the set's last parameter decides its fit: `pays` halves the chi-square, `cheap`
    // gains half its price, `fails` cannot be asked, `pinned` quarters it with every
    // candidate on its bound, the others change nothing; each wider question is started
    // from the plain one alone
    let asked = RefCell::new(Vec::<Vec<String>>::new());
    let fake = |gains: bool| {
        let (plain, asked) = (&plain, &asked);
        move |set: &[String], start: Start| -> Option<Asked> {
            assert!(
                matches!(start, Start::Only(w) if w.best_misfit().chi2() == chi2),
                "started from the plain alone"
            );
            asked.borrow_mut().push(set.to_vec());
            let last = set.last()?;
            let mut a = plain.clone();
            let factor = if gains && last == pays {
                0.5
            } else if last == cheap {
                (-0.5 * effective.ln() / effective).exp()
            } else if last == fails {
                return None;
            } else if last == pinned {
                let path = hbmodel::params::param(last).expect("registered").path;
                for c in &mut a.decision.candidates {
                    c.on_bound = Some((path, 1.0));
                }
                0.25
            } else {
                1.0
            };
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
            (0.15, &[]),
            &|_| cleared,
            &ask,
        );
        let expected: Vec<String> = [held].into_iter().chain(kept).cloned().collect();
        assert_eq!(set, expected, "gains: {gains}, cleared: {cleared}");
        assert!((a.best_misfit().chi2() / chi2 - factor).abs() < 1e-12);
        let calls = asked.take();
        assert_eq!(calls.len(), calls_made, "{calls:?}");
        assert!(calls
            .iter()
            .all(|c| c[0] == *held && c.len() == 2 && c[1] != *held));
    }

    // a recalibration the question held at the model's value is not offered again
    let ask = fake(true);
    let (set, _) = widened(
        &s.known,
        &between,
        (vec![held.clone()], plain.clone()),
        (0.15, std::slice::from_ref(pays)),
        &|_| false,
        &ask,
    );
    assert_eq!(set, std::slice::from_ref(held));
    let calls = asked.take();
    assert_eq!(calls.len(), widening - 1, "{calls:?}");
    assert!(calls.iter().all(|c| c[1] != *pays));
}

/// A hidden sensor delay's steps (Rust bench, seed 2), asked between a valve lag and the
/// delay from the known model with nothing re-fitted.
pub(super) fn delay_or_lag() -> (Setup, [String; 2], Asked) {
    let (s, records) = delay_on_steps();
    let target = target_of(&records).expect("a target");
    let names = vec!["steps".to_string()];
    let between = ["valve_dynamics".to_string(), "sensor_delay".to_string()];
    let asked = decision::ask(
        &s.known,
        &between,
        &[],
        (&target, &names),
        (0.15, false),
        Start::Cold,
    )
    .expect("the question");
    (s, between, asked)
}

/// A payload hidden with model-form error (Rust bench, +-10 mm steps, seed 3: the LVDT
/// lagging 0.25 ms, the bulk modulus 7 % low). Since `hide`'s lags act as drawn (session
/// 64) the payload is named at step 1 (3.00 kg against 2.35) by a hair over the
/// manifold's oil mass; the run then adds dry friction (5.0 N, an effect not hidden) and
/// recalibrates the bulk modulus. Asked again at the end, every candidate takes the bulk
/// modulus to a bound of its recalibration, so it is held at the model's value; the
/// payload wins clearly (ln B 82.8 over the oil mass) and the run stands, ending with the
/// payload 2.39 kg (measured, session 64; about 4 CPU min).
///
/// Until session 63 the LVDT's lag acted as 0.02 ms; the oil mass was then taken at step 1
/// by ln B 39, the later recalibrations moved it from 0.86 to 0.52, and the revision
/// asked step 1 again and continued from the payload (2.43 kg, session 26). Neither the
/// drawn lag nor a lag of 0.02 ms (measured, session 64: the oil mass then moves only
/// to 0.72, which asks nothing again) takes that path on the new `hide`; a run continued
/// from its rival is covered by
/// `a_contested_step_is_asked_again_and_the_run_continued_from_a_clear_rival`.
#[test]
fn a_payload_asked_again_beside_the_oil_mass_stands_with_the_bound_recalibration_held() {
    let s = Setup::new(Simulator::Rust, true, &[Effect::Payload], 3);
    let records = [record(&s, Kind::Steps, 3)];
    let settings = crate::gap::Settings {
        advise: false,
        ..crate::gap::Settings::default()
    };
    let o = crate::gap::run_with(&s.known, &records, settings).expect("the workflow runs");
    let first = o
        .steps
        .iter()
        .find(|s| s.kind == StepKind::Add)
        .expect("an effect");
    assert_eq!(first.name, "payload", "{}", o.verdict);
    let r = o.revision.as_ref().expect("a step was asked again");
    assert_eq!(r.step, 0, "{}", r.verdict);
    assert!(
        r.between.iter().any(|b| b == "manifold_inertia"),
        "{}",
        r.verdict
    );
    assert_eq!(r.held, ["fluid.bulk_modulus"], "{}", r.verdict);
    assert!(!r.revised, "{}", r.verdict);
    let d = &r.decision;
    assert_eq!(d.winner.as_deref(), Some("payload"), "{}", d.verdict);
    assert!(
        d.preference
            .as_ref()
            .is_some_and(|p| p.ln_bayes_factor >= CLEAR_LN_BAYES),
        "{}",
        d.verdict
    );
    let truth = s.drawn[0].1;
    let fitted = o.model.actuator.payload_mass;
    assert!(
        (fitted / truth - 1.0).abs() < 0.1,
        "{fitted} against {truth}"
    );
}

/// The manifold's oil mass hidden with model-form error (Rust bench, +-10 mm steps,
/// seed 1: the pressure sensors lagging 0.40 ms, SV1's null leakage 14 % high). Asked
/// between the volume and the oil mass from the known model, with SV1's null leakage,
/// the viscous friction and the bulk modulus re-fitted beside each, both fits end on the
/// bulk modulus's -15 %, which is held. Asked again without it but started from the
/// first question's fits (`fit::fit_warm`), the oil mass fits to gap 12.4 with its scale
/// 8 % under the truth (1.32 against 1.44); started cold, the same question leaves it at
/// 25.1, above the volume's 24.1 (measured, session 64). The warm fit is then refused on
/// the data it was not fitted on, and the volume stands: a miss of the run, counted in the
/// full study. While `hide`'s pressure lag acted as 0.09 ms (until session 63) the warm
/// fit reached 3.96 and won clearly, and the run continued from the oil mass (session 27).
/// About 10 CPU s.
#[test]
fn a_question_asked_again_starts_from_the_fits_before_it() {
    let s = Setup::new(Simulator::Rust, true, &[Effect::ManifoldInertia], 1);
    let records = [record(&s, Kind::Steps, 1)];
    let target = target_of(&records).expect("a target");
    let names = vec!["steps".to_string()];
    let between = [
        "manifold_volume".to_string(),
        "manifold_inertia".to_string(),
    ];
    let set = |paths: &[&str]| -> Vec<String> { paths.iter().map(|p| p.to_string()).collect() };
    // in the order the run re-fitted them
    let with_bulk = set(&[
        "sv1.null_leakage",
        "fluid.bulk_modulus",
        "actuator.viscous_friction",
    ]);
    let both = set(&["sv1.null_leakage", "actuator.viscous_friction"]);
    // at the workflow's tolerance, as the run asks it
    let known = crate::gap::at_rtol(&s.known, crate::gap::RTOL);
    let ask = |recalibrate: &[String], start: Start| {
        decision::ask(
            &known,
            &between,
            recalibrate,
            (&target, &names),
            (0.15, false),
            start,
        )
        .expect("the question")
    };
    let first = ask(&with_bulk, Start::Cold);
    assert_eq!(
        pinned_by_all(&first, &with_bulk).as_deref(),
        Some("fluid.bulk_modulus"),
        "{}",
        first.decision.verdict
    );
    let again = ask(&both, Start::Also(&first));
    // started cold, the oil mass's fit ends in another basin (25.1, measured), above the
    // volume's
    let cold = ask(&both, Start::Cold);
    let gap_of = |a: &Asked, name: &str| {
        a.fits
            .iter()
            .find(|f| f.name == name)
            .map(|f| f.gap)
            .expect("fitted")
    };
    let oil = gap_of(&again, "manifold_inertia");
    assert!(
        gap_of(&cold, "manifold_inertia") > 1.8 * oil,
        "{}",
        cold.decision.verdict
    );
    assert!(
        oil < gap_of(&cold, "manifold_volume"),
        "{}",
        cold.decision.verdict
    );
    let fit = again
        .fits
        .iter()
        .find(|f| f.name == "manifold_inertia")
        .expect("fitted");
    let fitted = fit.params.manifold.inertia_scale;
    let truth = s.drawn[0].1;
    assert!(
        (fitted / truth - 1.0).abs() < 0.1,
        "{fitted} against {truth}"
    );
    // the held-out check then refuses it under the 0.40 ms pressure lag (above): a miss
    // of the run, which this test of the warm start does not assert
}
