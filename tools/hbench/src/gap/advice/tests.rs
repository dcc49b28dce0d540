use hbmodel::effects::Effect;
use hbmodel::sensors::SensorParams;
use hbmodel::Params;

use super::super::blind::known_model;
use super::super::experiments::{designs, Design, Kind};
use super::super::Scored;
use super::plan::Question;
use super::recommendation::SAFE_LN_BAYES;
use super::recorded::observed;
use super::*;

/// The advice between `leading`, no design recorded: the separations at the noise floor
/// of correlation time `tau`.
fn advise(
    from: &Params,
    leading: &[(String, Params)],
    noise: &[(&'static str, f64)],
    tau: f64,
    designs: &[Design],
    progress: bool,
) -> Advice {
    let scale = Scale::new(tau, 1.0);
    recommend(
        from,
        leading,
        scale,
        assess(from, leading, noise, scale, designs, progress),
    )
}

/// The record's noise: that of the sensors `hide` samples with (SensorParams::default).
fn noise() -> Vec<(&'static str, f64)> {
    let sp = SensorParams::default();
    vec![
        ("y", sp.position_noise),
        ("P1", sp.pressure_noise),
        ("P2", sp.pressure_noise),
    ]
}

/// The known model and the same with a second-order spool lag at 1500 Hz (far faster
/// than the valve's tuned 440 Hz): a lag of about 2 zeta f / f_n rad in the loop at f,
/// 0.004 rad at the 5 Hz of the slow moves, 0.2 rad at the sweep's 300 Hz. Measured at the
/// sensors' noise (RMS separation in noise levels): sweep 2.5 s 51.9, 5 s 54.0; steps
/// +-10 mm 14.9 (the pressures ring after each step), +-2 mm 8.9; moves 1 s 0.075, 2 s
/// 0.023 (ln B 1.6); chirp 0.3 V 0.26, 1 V 0.91. The sweep must separate them by a factor
/// over every moves design; the advice must be the shortest design that separates them
/// safely (the steps, 0.65 s); with the slow moves alone it must say that nothing
/// separates them.
#[test]
fn a_fast_valve_lag_is_told_apart_on_a_sweep_not_on_slow_moves() {
    let known = known_model(&[]);
    let mut lagged = known.clone();
    lagged.effects.set(Effect::ValveDynamics, true);
    lagged.sv1.natural_frequency = 2.0 * std::f64::consts::PI * 1500.0;
    let leading = vec![
        ("as is".to_string(), known),
        ("valve_dynamics".to_string(), lagged),
    ];
    let a = advise(&leading[0].1, &leading, &noise(), 1.0, &designs(), false);
    for d in &a.designs {
        let p = d.pairs.first();
        eprintln!(
            "{}: {:?} {:?}",
            d.label,
            p.map(|p| (p.rms, p.ln_bayes_factor)),
            d.error
        );
    }
    let rms = |kind: Kind| {
        a.designs
            .iter()
            .filter(|d| d.design.kind == kind)
            .filter_map(|d| d.pairs.first().map(|p| p.rms))
            .fold(0.0, f64::max)
    };
    // after the refit (`refit`: the valve's flow and the loop's other recalibrations
    // take up part of a lag's gain and phase) sweep 5 s 19.3, 2.5 s 15.6, steps +-10 mm
    // 10.8, +-2 mm 5.6, moves 1 s 0.063, chirp 1 V 0.70 (measured); raw, the sweep stood
    // 3.5 times over the steps
    assert!(
        rms(Kind::Sweep) > 3.0 * rms(Kind::Moves) && rms(Kind::Sweep) > 1.5 * rms(Kind::Steps),
        "sweep {:.3} against moves {:.3}, steps {:.3}",
        rms(Kind::Sweep),
        rms(Kind::Moves),
        rms(Kind::Steps)
    );
    let best = a
        .designs
        .iter()
        .find(|d| Some(&d.label) == a.best.as_ref())
        .expect("a best design");
    let least = best.least_ln_bayes_factor.unwrap();
    assert!(
        a.separates && least >= SAFE_LN_BAYES,
        "{}",
        a.recommendation
    );
    for d in &a.designs {
        if d.design.duration < best.design.duration {
            assert!(
                d.least_ln_bayes_factor.unwrap_or(0.0) < SAFE_LN_BAYES,
                "{} is shorter than {} and separates too",
                d.label,
                best.label
            );
        }
    }
    assert_eq!(best.design.kind, Kind::Steps, "{}", a.recommendation);

    let slow_moves = Design {
        duration: 2.0,
        ..Design::standard(Kind::Moves)
    };
    let a = advise(&leading[0].1, &leading, &noise(), 1.0, &[slow_moves], false);
    let p = &a.designs[0].pairs[0];
    assert!(p.rms < 0.1 && p.ln_bayes_factor < CLEAR_LN_BAYES, "{p:?}");
    assert!(
        !a.separates
            && a.recommendation
                .starts_with("none of the experiments separates as is from valve_dynamics"),
        "{}",
        a.recommendation
    );
}

/// Identical models cannot be separated by any experiment: zero separation everywhere and
/// the advice says so. A design the bench cannot run (zero amplitude) is reported, not a
/// panic.
#[test]
fn identical_models_are_separated_by_no_advice() {
    let p = known_model(&[]);
    let leading = vec![("as is".to_string(), p.clone()), ("twin".to_string(), p)];
    let broken = Design {
        amplitude: 0.0,
        ..Design::standard(Kind::Steps)
    };
    let a = advise(
        &leading[0].1,
        &leading,
        &noise(),
        3.0,
        &[Design::standard(Kind::Steps), broken],
        false,
    );
    assert_eq!(a.designs[0].pairs[0].chi2, 0.0);
    assert!(!a.separates);
    assert!(
        a.recommendation
            .starts_with("none of the experiments separates as is from twin"),
        "{}",
        a.recommendation
    );
    assert!(a.designs[1].error.is_some() && a.designs[1].least_ln_bayes_factor.is_none());
}

fn scored(effect: &str, score: f64) -> Scored {
    Scored {
        effect: effect.into(),
        gap: 1.0,
        score,
        parameters: Default::default(),
        on_bound: None,
        bounded: Vec::new(),
        trades: None,
    }
}

fn fitted(name: &str, score: f64) -> (f64, Fit) {
    let params = Params::default();
    let fit = Fit {
        candidate: super::super::effects::Candidate {
            kind: super::super::effects::StepKind::Add,
            effect: None,
            fitted: Vec::new(),
            signature: "",
            switches_on: &[],
        },
        carried: Vec::new(),
        name: name.into(),
        params,
        values: Vec::new(),
        chi2: 0.0,
        objective: 0.0,
        gap: 1.0,
        signal_gaps: Vec::new(),
        record_chi2: Vec::new(),
    };
    (score, fit)
}

/// The advice is asked for when the two best candidates are within ln B 3 (scores within
/// 6), or when the run ends above the noise floor, and not when the record decided;
/// the leading models are the model as is and the two best of the last round, the one the
/// model already holds and failed fits left out.
#[test]
fn the_advice_is_asked_when_the_record_leaves_the_leaders_undecided() {
    // at the noise floor nothing is asked (close rejected scores are no question the
    // data raise); above it, what is missing is
    assert!(!needed(&[], 1.0));
    assert!(!needed(&[], 1.05));
    assert!(needed(&[], 2.0));
    let model = Params::default();
    let round = vec![
        fitted("x", 5.0),
        fitted("y", 9.0),
        fitted("z", 7.0),
        fitted("w", f64::NAN),
    ];
    let names = |l: Vec<(String, Params)>| l.into_iter().map(|(n, _)| n).collect::<Vec<_>>();
    assert_eq!(
        names(leading(&model, &round, Some("y"))),
        ["as is", "z", "x"]
    );
    assert_eq!(names(leading(&model, &round, None)), ["as is", "y", "z"]);
    let rounds = [Round {
        start: Params::default(),
        tau: 1.0,
        fits: round,
    }];
    assert!(Question::of(&model, &[], 1.05, &rounds).is_none());
}

/// On slow 7th-order moves of the known model, the oil's compliance hardly matters: the
/// manifold's volume and 0.8 % entrained air (the middles of their plausible ranges)
/// change the record by less than ln B 3 (measured), while a dry friction of 85 N stops
/// the piston short of each end and a 374 Hz spool lag shows in the loop's transients:
/// the first two are blind spots of the record, the others are not.
#[test]
fn slow_moves_cannot_show_the_oils_compliance_but_show_friction() {
    use super::super::fit::{Record, Target};
    use super::super::hide::measure;
    let known = known_model(&[]);
    let (experiment, measured) = measure(&known, Kind::Moves, 1).expect("the bench runs");
    let target = Target {
        records: vec![Record::new(&measured, &experiment, noise())],
        variance: Default::default(),
    };
    let spots = unseen::blind_spots(&known, &target, 1.0);
    let names: Vec<&str> = spots.iter().map(|(n, _, _)| n.as_str()).collect();
    assert!(
        names.contains(&"entrained_air") && names.contains(&"manifold_volume"),
        "{names:?}"
    );
    assert!(
        !names.contains(&"dry_friction") && !names.contains(&"valve_dynamics"),
        "{names:?}"
    );
    assert!(spots.iter().all(|(_, _, b)| *b < CLEAR_LN_BAYES));
}

/// On the 1 V chirp at the thesis's 210 bar, entrained air at the middle of its plausible
/// range changes the record, but a re-fitted bulk modulus (and the other recalibrations)
/// takes that change up: the record cannot show the air, and the advice says so. Before
/// the refit the unseen check read the raw change and called the air seen: on the Rust
/// bench's chirps (form error, seed 1) with nothing, a dry friction, the manifold's volume
/// or a valve lag hidden, each explained within its noise, no advice was given; now each
/// names the air (ln B 0.0-1.7 left) and recommends the 50 bar steps (session 56,
/// measured). The manifold's volume, which moves the loop's resonance, stays seen.
#[test]
fn a_chirp_at_the_thesis_supply_cannot_show_air_once_the_oil_is_refitted() {
    use super::super::fit::{Record, Target};
    use super::super::hide::measure;
    let known = known_model(&[]);
    let (experiment, measured) = measure(&known, Kind::Chirp, 1).expect("the bench runs");
    let target = Target {
        records: vec![Record::new(&measured, &experiment, noise())],
        variance: Default::default(),
    };
    let spots = unseen::blind_spots(&known, &target, 1.0);
    let names: Vec<&str> = spots.iter().map(|(n, _, _)| n.as_str()).collect();
    assert!(names.contains(&"entrained_air"), "{names:?}");
    assert!(!names.contains(&"manifold_volume"), "{names:?}");
}

/// A step taken against a rival within ln B 3 that paid its price.
pub(super) fn step(name: &str, scores: &[(&str, f64)]) -> Step {
    let candidates: Vec<Scored> = scores.iter().map(|&(n, v)| scored(n, v)).collect();
    let ranked: Vec<(String, f64)> = scores.iter().map(|&(n, v)| (n.into(), v)).collect();
    Step {
        kind: super::super::effects::StepKind::Add,
        effect: Some(name.into()),
        name: name.into(),
        brings: Vec::new(),
        parameters: Default::default(),
        gap_before: 2.0,
        gap_after: 1.5,
        candidates,
        effective_samples: 100.0,
        preference: super::super::evidence::preference(&ranked),
        validation: None,
        spread: Vec::new(),
        signals: Vec::new(),
    }
}

/// A round from the default model whose candidates scored `names`, its residual's
/// correlation time 2.
pub(super) fn round(names: &[(&str, f64)]) -> Round {
    Round {
        start: Params::default(),
        tau: 2.0,
        fits: names.iter().map(|&(n, v)| fitted(n, v)).collect(),
    }
}

/// The advice asks about the earliest step the record could not decide, with the two fits
/// of that step's round: a later clear step does not hide it, a step whose rival did not
/// pay its price is no question, and where a recalibration was taken over a close effect
/// the effect is the rival.
#[test]
fn the_advice_asks_the_earliest_undecided_step() {
    let first = [("inertia", 40.0), ("payload", 38.0), ("volume", 10.0)];
    let second = [("delay", 30.0), ("air", 5.0)];
    let steps = [step("inertia", &first), step("delay", &second)];
    let rounds = [round(&first), round(&second)];
    assert!(needed(&steps, 1.0));
    let u = earliest_contested(&steps, &rounds).expect("step 1 was undecided");
    let [a, b] = &u.pair;
    assert_eq!(
        (u.step, u.tau, a.0.as_str(), b.0.as_str()),
        (0, 2.0, "inertia", "payload")
    );
    // a rival that did not pay its price is no question; the clear second step is none
    let unpaid = [("inertia", 4.0), ("payload", -1.0)];
    let steps = [step("inertia", &unpaid), step("delay", &second)];
    let rounds = [round(&unpaid), round(&second)];
    assert!(earliest_contested(&steps, &rounds).is_none());
    assert!(!needed(&steps, 1.0));
    // a recalibration taken over the best effect: the effect is the rival
    let recal = [("leakage", 20.0), ("viscous", 17.0)];
    let steps = [step("viscous", &recal)];
    let u = earliest_contested(&steps, &[round(&recal)]).expect("undecided");
    let [a, b] = &u.pair;
    assert_eq!((a.0.as_str(), b.0.as_str()), ("viscous", "leakage"));
}

/// A payload of 3.18 kg (the blind study's, seed 1) makes section 4.4's model
/// limit-cycle about each set point of +-2 mm steps, while the model without it comes to
/// rest: the design is not assessed for that pair (a cycle's phase is no evidence), and on
/// +-10 mm steps, where both come to rest, it is.
#[test]
fn a_design_under_which_a_leading_model_oscillates_is_not_recommended() {
    let known = super::super::variants::section_4_4();
    let mut heavy = known.clone();
    heavy.effects.set(Effect::Payload, true);
    heavy.actuator.payload_mass = 3.18;
    let small = Design {
        amplitude: 2e-3,
        ..Design::standard(Kind::Steps)
    };
    let sigma = SensorParams::default().pressure_noise;
    let rest = simulate(&known, &small).expect("runs").held_ripple;
    let cycle = simulate(&heavy, &small).expect("runs").held_ripple;
    assert!(rest < 3.0 * sigma, "the known model rests: {rest} Pa");
    assert!(
        cycle > validity::OSCILLATION_LEVELS * sigma,
        "the payload cycles: {cycle} Pa"
    );
    let leading = vec![("as is".to_string(), known), ("payload".to_string(), heavy)];
    let a = advise(
        &leading[0].1,
        &leading,
        &noise(),
        1.0,
        &[small, Design::standard(Kind::Steps)],
        false,
    );
    let e = a.designs[0].error.as_deref().unwrap_or("");
    assert!(e.contains("`payload` oscillates on its own"), "{e}");
    assert!(a.designs[1].error.is_none(), "{:?}", a.designs[1].error);
    assert_eq!(a.best.as_deref(), Some(a.designs[1].label.as_str()));
}

/// The oil's range (`validity`): section 4.4's model stays inside it under every design
/// the advice compares (measured 2.3-209.9 bar), so no design is declined for the model a
/// user starts from; a 3.18 kg payload, near the loop's stability limit, pulls a chamber
/// into the cavitation band on the sweep (measured 0.07 bar), and the sweep is then not
/// assessed while the chirp is.
#[test]
fn a_design_under_which_a_leading_model_cavitates_is_not_recommended() {
    let known = super::super::variants::section_4_4();
    for d in designs() {
        let s = simulate(&known, &d).expect("runs");
        let e = validity::no_evidence(AS_IS, &s, 0.0);
        assert!(e.is_none(), "{}: {e:?}", d.label());
    }
    let mut heavy = known.clone();
    heavy.effects.set(Effect::Payload, true);
    heavy.actuator.payload_mass = 3.18;
    let (sweep, chirp) = (Design::standard(Kind::Sweep), Design::standard(Kind::Chirp));
    let leading = vec![(AS_IS.to_string(), known), ("payload".to_string(), heavy)];
    let a = advise(
        &leading[0].1,
        &leading,
        &noise(),
        1.0,
        &[sweep, chirp],
        false,
    );
    let e = a.designs[0].error.as_deref().unwrap_or("");
    assert!(e.contains("`payload` leaves the oil's range"), "{e}");
    assert!(a.designs[1].error.is_none(), "{:?}", a.designs[1].error);
    assert_eq!(a.best.as_deref(), Some(a.designs[1].label.as_str()));
}

/// The expected ln B is what `evidence::score` finds between the two models on a record
/// whose right model leaves a form error of m - 1 noise variances: a record of n = 4000
/// samples made of model a, a smooth form error of RMS 3 noise levels (m = 10) and white
/// noise; model b off from a by 0.5 noise levels RMS. Read against the sensor noise alone
/// the expectation would be D / 2 = 500, ten times what the score finds.
#[test]
fn the_expected_separation_is_what_the_scores_find_under_form_error() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let n = 4000;
    let white = Normal::new(0.0, 1.0).unwrap();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let a: Vec<[f64; 3]> = (0..n).map(|_| [0.0; 3]).collect();
    let b: Vec<[f64; 3]> = (0..n)
        .map(|k| [0.5 * 2f64.sqrt() * (k as f64 * 0.05).sin(), 0.0, 0.0])
        .collect();
    // form error slow against b's difference (uncorrelated with it), RMS 3
    let data: Vec<f64> = (0..n)
        .map(|k| 3.0 * 2f64.sqrt() * (k as f64 * 0.0031 + 0.4).sin() + white.sample(&mut rng))
        .collect();
    let chi2 =
        |m: &[[f64; 3]]| -> f64 { m.iter().zip(&data).map(|(x, d)| (d - x[0]).powi(2)).sum() };
    let found = (evidence_score(chi2(&b), chi2(&a), n as f64)) / 2.0;
    let noise = [("y", 1.0)];
    let s = separation(("a", &a), ("b", &b), &noise, Scale::new(1.0, 10f64.sqrt()));
    assert!((s.rms - 0.5).abs() < 0.01, "{s:?}");
    assert!(
        (s.ln_bayes_factor / found - 1.0).abs() < 0.2,
        "expected {:.1}, the scores find {found:.1}",
        s.ln_bayes_factor
    );
    let at_noise = separation(("a", &a), ("b", &b), &noise, Scale::new(1.0, 1.0));
    assert!(at_noise.ln_bayes_factor > 5.0 * found, "{at_noise:?}");
}

/// ln B between the same k: `evidence::score`'s drop from `before` to `after` over `n`
/// independent samples.
fn evidence_score(before: f64, after: f64, n: f64) -> f64 {
    super::super::evidence::score(before, after, n, 0.0)
}

/// The records' own design is recognised (hide's steps and chirp records, the chirp's
/// commands through the 16-bit converter), a record of other amplitude is none of them,
/// and a design they hold is read at the ln B they showed, not the 10^3 the models'
/// difference alone would promise.
#[test]
fn a_design_the_records_hold_is_read_at_what_they_showed() {
    use super::super::experiments::design_of;
    use super::super::hide::{measure, measure_under};
    let known = known_model(&[]);
    for kind in [Kind::Steps, Kind::Chirp] {
        let (e, m) = measure(&known, kind, 1).expect("the bench runs");
        assert_eq!(design_of(&e, &m), Some(Design::standard(kind)), "{kind:?}");
    }
    let other = Design {
        amplitude: 5e-3,
        ..Design::standard(Kind::Steps)
    };
    let (e, m) = measure_under(&known, &other, 1).expect("the bench runs");
    assert_eq!(design_of(&e, &m), None);

    let mut lagged = known.clone();
    lagged.effects.set(Effect::ValveDynamics, true);
    lagged.sv1.natural_frequency = 2.0 * std::f64::consts::PI * 1500.0;
    let leading = vec![
        (AS_IS.to_string(), known),
        ("valve_dynamics".to_string(), lagged),
    ];
    let steps = Design::standard(Kind::Steps);
    let scale = Scale::new(1.0, 1.0);
    let from = leading[0].1.clone();
    let mut assessed = assess(&from, &leading, &noise(), scale, &[steps, other], false);
    let promised = assessed[0].least_ln_bayes_factor.unwrap();
    assert!(promised > 1e3, "{promised}");
    recorded::read_at_records(&mut assessed, &[steps], |_, _| Some(1.5));
    assert_eq!(assessed[0].least_ln_bayes_factor, Some(1.5));
    assert_eq!(assessed[0].pairs[0].recorded, Some(1.5));
    // what the simulations promised stays beside it in report.json
    assert_eq!(assessed[0].pairs[0].simulated, promised);
    assert!(assessed[1].pairs[0].recorded.is_none());
    let a = recommend(&leading[0].1, &leading, scale, assessed);
    assert_eq!(
        a.best.as_deref(),
        Some(other.label().as_str()),
        "{}",
        a.recommendation
    );
}

/// The ln B a round showed between two of its fits, or between the model as it stands
/// (0 against the round's start, or the winner it took) and a fit.
#[test]
fn the_separation_a_round_showed() {
    let fits = vec![fitted("x", 9.0), fitted("y", 5.0), fitted("z", f64::NAN)];
    assert_eq!(observed(&fits, None, "x", "y"), Some(2.0));
    assert_eq!(observed(&fits, None, AS_IS, "y"), Some(2.5));
    assert_eq!(observed(&fits, Some("x"), AS_IS, "y"), Some(2.0));
    assert_eq!(observed(&fits, None, AS_IS, "z"), None);
}

/// The low-supply steps tell entrained air from a bulk modulus a few percent off, which
/// tie at the thesis's 210 bar: on the Rust moves seed 2 case with 0.23 % of air hidden
/// and the modulus 3.3 % low by form error, the advised 210 bar steps fitted either
/// equally well (gap 2.18, ln B 0.2, session 53). Each model's departure from the known
/// model's pressures, air against the softer oil, grows several-fold at 50 bar supply:
/// the air's stiffness loss grows as 1/p^2 (A.9-A.12), the modulus's does not.
#[test]
fn low_supply_sets_air_apart_from_the_bulk_modulus() {
    let known = crate::gap::variants::section_4_4();
    let mut air = known.clone();
    air.effects.set(Effect::EntrainedAir, true);
    air.fluid.air_fraction = 0.0023;
    let mut soft = known.clone();
    soft.fluid.bulk_modulus *= 0.967;
    let thesis = Design::standard(Kind::Steps);
    let low = designs()
        .into_iter()
        .find(|d| d.supply < thesis.supply)
        .expect("the advice compares a low-supply design");
    let ratio = |d: &Design| {
        let base = simulate(&known, d).expect("runs").traces;
        let departure = |p: &Params| {
            let t = simulate(p, d).expect("runs").traces;
            let ss: f64 = t
                .iter()
                .zip(&base)
                .map(|(a, b)| (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2))
                .sum();
            ss.sqrt()
        };
        departure(&air) / departure(&soft)
    };
    let (at_210, at_50) = (ratio(&thesis), ratio(&low));
    eprintln!("air against the softer oil: {at_210:.3} at 210 bar, {at_50:.3} at 50 bar");
    assert!(
        at_50 > 5.0 * at_210,
        "{at_210:.3} at 210 bar, {at_50:.3} at 50 bar"
    );
}

/// The refit the new record's analysis makes takes the air up at the thesis's supply and
/// not at 50 bar: what `low_supply_sets_air_apart_from_the_bulk_modulus` shows of the
/// two models' runs, read as the advice now reads a pair (`refit`). Measured on the Rust
/// moves (form error, seed 1; the air at its plausible middle), the as-is / air pair of the
/// +-10 mm steps went from ln B 298 to 3.0 (99 % taken up by the recalibrations), on the
/// 50 bar steps from 1255 to 442 (78 %).
#[test]
fn a_refit_takes_the_air_up_at_the_thesis_supply_and_not_at_50_bar() {
    let known = crate::gap::variants::section_4_4();
    let mut air = known.clone();
    air.effects.set(Effect::EntrainedAir, true);
    air.fluid.air_fraction = 0.0023;
    let thesis = Design::standard(Kind::Steps);
    let low = designs()
        .into_iter()
        .find(|d| d.supply < thesis.supply)
        .expect("the advice compares a low-supply design");
    let leading = vec![
        (AS_IS.to_string(), known.clone()),
        ("entrained_air".to_string(), air),
    ];
    let noise = noise();
    let assessed = assess(
        &known,
        &leading,
        &noise,
        Scale::new(1.0, 1.0),
        &[thesis, low],
        false,
    );
    let pair = |a: &Assessed| a.pairs.first().cloned().expect("assessed");
    let (at_210, at_50) = (pair(&assessed[0]), pair(&assessed[1]));
    eprintln!(
        "taken up: {:.3} at 210 bar (ln B {:.1}), {:.3} at 50 bar (ln B {:.1})",
        at_210.absorbed, at_210.ln_bayes_factor, at_50.absorbed, at_50.ln_bayes_factor
    );
    // measured: 0.997 taken up at 210 bar (ln B 0.1), 0.955 at 50 bar (ln B 11.6): the
    // recalibrations take most of the air's compliance up at either supply, and only its
    // pressure dependence is left, which the low supply shows clearly
    assert!(at_210.absorbed > 0.99, "{at_210:?}");
    assert!(at_210.ln_bayes_factor < CLEAR_LN_BAYES, "{at_210:?}");
    assert!(at_50.absorbed < at_210.absorbed, "{at_50:?}");
    assert!(
        at_50.ln_bayes_factor > CLEAR_LN_BAYES
            && at_50.ln_bayes_factor > 10.0 * at_210.ln_bayes_factor,
        "{at_210:?} {at_50:?}"
    );
}

/// The bounded refit: what lies outside the columns' span is left, a coefficient is
/// held within its range, and nothing is ever left beyond the difference itself.
#[test]
fn a_bounded_refit_leaves_what_the_columns_cannot_reach() {
    use nalgebra::DVector;
    let e = |i: usize| DVector::from_fn(3, |k, _| if k == i { 1.0 } else { 0.0 });
    let d = e(0) * 2.0 + e(1) * 0.5 + e(2) * 0.3;
    let columns = [e(0), e(1) * 2.0];
    // free within wide ranges: only the third component is left
    let free = refit::unexplained(&d, &columns, &[[-10.0, 10.0], [-10.0, 10.0]]);
    assert!((free - 0.09).abs() < 1e-9, "{free}");
    // the first held to at most 1: one unit of it is left too
    let held = refit::unexplained(&d, &columns, &[[-1.0, 1.0], [-10.0, 10.0]]);
    assert!((held - 1.09).abs() < 1e-9, "{held}");
    // nearly collinear columns, each bounded the wrong way: never more than |d|^2
    let skew = [e(0) + e(1) * 1e-6, e(0) * -1.0];
    let worst = refit::unexplained(&d, &skew, &[[-0.5, 0.0], [-0.5, 0.0]]);
    assert!(worst <= d.norm_squared() + 1e-12, "{worst}");
}
