use super::*;

#[test]
fn coordinates_stay_in_bounds_and_invert() {
    for f in super::super::effects::all()
        .iter()
        .flat_map(|c| c.fitted.clone())
    {
        let c = Coordinate::new(&f);
        for z in [-40.0, -3.0, 0.0, 2.0, 40.0] {
            let v = c.value(z);
            let slack = 1e-12 * (c.hi - c.lo);
            assert!(v >= c.lo - slack && v <= c.hi + slack, "{} {v}", f.path);
        }
        let mid = 0.5 * (f.plausible[0] + f.plausible[1]);
        let back = c.value(c.coordinate(mid));
        assert!(
            (back / mid - 1.0).abs() < 1e-9,
            "{}: {mid} -> {back}",
            f.path
        );
    }
}

/// The spread says what a record pins. A sensor delay hidden in +-10 mm steps is
/// pinned (standard error a few percent of it, the truth within three of them). On
/// the same steps the Coulomb friction, fitted with the viscous friction carried,
/// trades against it: the pistons cross the stroke at a near constant speed, where
/// the two forces are alike.
#[test]
fn the_spread_pins_a_delay_and_finds_dry_and_viscous_friction_traded_on_steps() {
    use crate::gap::blind::Setup;
    use crate::gap::effects::candidate;
    use crate::gap::hide::Kind;
    use crate::gap::recalibrate;
    use crate::gap::target_of;
    use crate::gap::tests::record;
    use crate::gap::variants::Simulator;

    let steps = |s: &Setup, seed: u64| record(s, Kind::Steps, seed);
    let s = Setup::new(Simulator::Rust, false, &[Effect::SensorDelay], 2);
    let records = [steps(&s, 2)];
    let target = target_of(&records).expect("a target");
    let c = candidate(Effect::SensorDelay).expect("a candidate");
    let f = fit(&target, &s.known, &c, &[]);
    let sp = spread(&target, &f, 1.0);
    let truth = s.drawn[0].1;
    let std = sp[0].std.expect("pinned");
    // 304.0 +- 1.0 us against 305.8 us, measured
    assert!(std < 0.05 * sp[0].value, "{sp:?}");
    assert!(
        (sp[0].value - truth).abs() < 3.0 * std,
        "{sp:?} against {truth}"
    );
    assert!(sp[0].most_correlated.is_none(), "one parameter");

    let s = Setup::new(Simulator::Rust, true, &[Effect::DryFriction], 1);
    let records = [steps(&s, 1)];
    let target = target_of(&records).expect("a target");
    let viscous = recalibrate::candidates(&s.known, 0.15, &[])
        .into_iter()
        .find(|c| c.name() == "actuator.viscous_friction")
        .expect("the viscous friction is on");
    let c = candidate(Effect::DryFriction).expect("a candidate");
    let f = fit(&target, &s.known, &c, &viscous.fitted);
    let sp = spread(&target, &f, 1.0);
    // -0.96, measured (seed 1 with its form error; -0.81 while the law's turn was held
    // at the known 45 mm/s, session 50)
    let Correlation { with, r } = sp[0].most_correlated.expect("three parameters");
    assert_eq!(with, "actuator.viscous_friction");
    assert!(r < -0.7, "{sp:?}");
    let viscous = sp
        .iter()
        .find(|x| x.path == "actuator.viscous_friction")
        .expect("the viscous friction's spread");
    assert_eq!(
        viscous.most_correlated.map(|m| (m.with, m.r)),
        Some(("friction.coulomb", r)),
        "symmetric"
    );
    assert!(sp.iter().all(|x| x.std.is_some_and(|d| d > 0.0)), "{sp:?}");
}

/// A fit stopped by a bound, of its own parameter or of one carried with it, is told;
/// one inside its bounds is not, nor one at a physical bound, unless the effect fitted to
/// its absence switched others on.
#[test]
fn a_fit_that_ended_on_a_bound_is_told() {
    use crate::gap::effects::candidate;
    let c = candidate(Effect::SensorDelay).expect("a candidate");
    let [floor, _] = c.fitted[0].bounds.expect("a floor");
    let bulk = Fitted {
        path: "fluid.bulk_modulus",
        plausible: [1.445e9, 1.955e9],
        log: false,
        either_sign: false,
        bounds: Some([1.445e9, 1.955e9]),
        drawn: true,
        floor_accepted: false,
    };
    let fit_at = |delay: f64, modulus: f64| {
        ended_at(
            &c,
            vec![bulk],
            vec![("sensors.delay", delay), ("fluid.bulk_modulus", modulus)],
        )
    };
    assert_eq!(fit_at(0.4e-3, 1.6e9).on_bound(), None);
    assert_eq!(
        fit_at(floor, 1.6e9).on_bound(),
        Some(("sensors.delay", floor))
    );
    assert_eq!(
        fit_at(0.4e-3, 1.445e9).on_bound(),
        Some(("fluid.bulk_modulus", 1.445e9))
    );
    // 1 % of the span inside the bound is inside
    assert_eq!(fit_at(0.4e-3, 1.445e9 + 0.01 * 0.51e9).on_bound(), None);
    // a physical bound, where the effect is none, does not count: such a fit adds
    // nothing and stays a fair rival
    let air = candidate(Effect::EntrainedAir).expect("a candidate");
    let none = Coordinate::new(&air.fitted[0]).lo;
    let at_none = ended_at(&air, vec![], vec![("fluid.air_fraction", none)]);
    assert_eq!(at_none.on_bound(), None);
    // but an effect that switches others on, fitted to its absence, is theirs: the
    // manifold's losses at scale 0 are its passages without losses
    let losses = candidate(Effect::ManifoldLosses).expect("a candidate");
    let at = |scale: f64| ended_at(&losses, vec![], vec![("manifold.loss_scale", scale)]);
    assert_eq!(at(0.0).on_bound(), Some(("manifold.loss_scale", 0.0)));
    assert_eq!(at(1.0).on_bound(), None);
    // at its physical ceiling it is no absence, but the ceiling stopped it: the data
    // asked for more loss than the law allows
    assert_eq!(at(10.0).on_bound(), Some(("manifold.loss_scale", 10.0)));
    assert_eq!(at(9.0).on_bound(), None);
    // as they asked for more air than the registry's 10 % (the peer's joint volume)
    let at_ceiling = ended_at(&air, vec![], vec![("fluid.air_fraction", 0.1)]);
    assert_eq!(at_ceiling.on_bound(), Some(("fluid.air_fraction", 0.1)));
    // and at a floor of the law that is no absence: passages of 0.3 of Table 3.3's
    // volume are the data asking for less than the law allows, not for no passages
    let volume = candidate(Effect::ManifoldVolume).expect("a candidate");
    let at = |scale: f64| ended_at(&volume, vec![], vec![("manifold.volume_scale", scale)]);
    assert_eq!(at(0.3).on_bound(), Some(("manifold.volume_scale", 0.3)));
    assert_eq!(at(0.35).on_bound(), None);
    // while the null leakage's log floor, three decades under its plausible range, is
    // the absence of leakage
    let leak = candidate(Effect::InternalLeakage).expect("a candidate");
    let none = Coordinate::new(&leak.fitted[0]).lo;
    let at_none = ended_at(&leak, vec![], vec![("sv1.null_leakage", none)]);
    assert_eq!(at_none.on_bound(), None);
    // and so is an effect whose size fitted to none while its law's other parameters
    // still act: the dry friction at 0 N Coulomb is its static peak alone
    let dry = candidate(Effect::DryFriction).expect("a candidate");
    let [sharpest, smoothest] = dry.fitted[1].bounds.expect("the turn's bounds");
    let at_turn = |f_c: f64, v0: f64| {
        ended_at(
            &dry,
            vec![],
            vec![
                ("friction.coulomb", f_c),
                ("friction.stribeck_velocity", v0),
            ],
        )
    };
    let at = |f_c: f64| at_turn(f_c, 1e-3);
    assert_eq!(at(0.0).on_bound(), Some(("friction.coulomb", 0.0)));
    assert_eq!(at(27.6).on_bound(), None);
    // a turn on the fit's floor (a cost limit) is a dry contact the data support; one at
    // the registry's smoothest is a viscous law below 0.1 m/s, which they asked for
    assert_eq!(at_turn(82.6, sharpest).on_bound(), None);
    assert_eq!(
        at_turn(82.6, smoothest).on_bound(),
        Some(("friction.stribeck_velocity", smoothest))
    );
    // a recalibration of the friction already on is no added effect: its floor of none
    // is a fit the data chose
    let mut re = dry.clone();
    re.kind = crate::gap::effects::StepKind::Recalibrate;
    let at = |f_c: f64| ended_at(&re, vec![], vec![("friction.coulomb", f_c)]);
    assert_eq!(at(0.0).on_bound(), None);
    // but a parameter of the model re-fitted beside a candidate, within its registry
    // bounds, at their ceiling is: the candidate stretched the model's law past what it
    // can be (the peer chirp's asymmetry with the viscous friction at 5000 N s/m)
    let mut viscous = candidate(Effect::ViscousFriction).expect("a candidate");
    viscous.kind = crate::gap::effects::StepKind::Recalibrate;
    let asymmetry = candidate(Effect::ValveAsymmetry).expect("a candidate");
    let beside = |b: f64| {
        // the asymmetry's own parameters inside their bounds
        let mut values: Vec<(&'static str, f64)> = asymmetry
            .fitted
            .iter()
            .map(|f| (f.path, 0.5 * (f.plausible[0] + f.plausible[1])))
            .collect();
        values.push(("actuator.viscous_friction", b));
        ended_at(&asymmetry, viscous.fitted.clone(), values)
    };
    assert_eq!(beside(400.0).on_bound(), None);
    assert_eq!(
        beside(5000.0).on_bound(),
        Some(("actuator.viscous_friction", 5000.0))
    );
    // its floor of none (no viscous friction) stays a fit the data chose
    assert_eq!(beside(0.0).on_bound(), None);
    // and so for the recalibration's own fit
    let at = |b: f64| ended_at(&viscous, vec![], vec![("actuator.viscous_friction", b)]);
    assert_eq!(at(0.0).on_bound(), None);
    assert_eq!(at(1200.0).on_bound(), None);
    assert_eq!(
        at(5000.0).on_bound(),
        Some(("actuator.viscous_friction", 5000.0))
    );
    // both stretch the model past its physical range, which an added effect's own
    // ceiling does not (it is a law the data asked too much of, not the model)
    assert!(beside(5000.0).stretches_model() && at(5000.0).stretches_model());
    assert!(!beside(400.0).stretches_model());
    let mut own: Vec<(&'static str, f64)> = asymmetry
        .fitted
        .iter()
        .map(|f| (f.path, f.plausible[1]))
        .collect();
    own[0].1 = hbmodel::params::param(own[0].0)
        .expect("in the registry")
        .max;
    own.push(("actuator.viscous_friction", 400.0));
    let own = ended_at(&asymmetry, viscous.fitted.clone(), own);
    assert!(
        own.on_bound().is_some() && !own.stretches_model(),
        "{:?}",
        own.values
    );
}

/// The spread reports the value the fit ended at, even nearer a bound than the clamp of
/// its coordinate (a millionth of the span): docs/gap_example's report gave a loss scale
/// fitted to 4.2e-7 as 1.0e-5 in its "Fitted" line and as 4.2e-7 in its table.
#[test]
fn the_spread_reports_a_value_next_to_its_bound_as_fitted() {
    use crate::gap::blind::Setup;
    use crate::gap::effects::candidate;
    use crate::gap::hide::Kind;
    use crate::gap::target_of;
    use crate::gap::tests::record;
    use crate::gap::variants::Simulator;

    let s = Setup::new(Simulator::Rust, false, &[], 1);
    let records = [record(&s, Kind::Steps, 1)];
    let target = target_of(&records).expect("a target");
    let c = candidate(Effect::DryFriction).expect("a candidate");
    let coordinate = Coordinate::new(&c.fitted[0]);
    assert!(
        !c.fitted[0].log,
        "a linear coordinate: its clamp is a millionth of the span"
    );
    let near = coordinate.lo + 1e-8 * (coordinate.hi - coordinate.lo);
    let mut params = s.known.clone();
    params.effects.set(Effect::DryFriction, true);
    param(c.fitted[0].path)
        .expect("registered")
        .set(&mut params, near);
    // the law's turn where the known model has it
    let turn = c.fitted[1].path;
    let values = vec![
        (c.fitted[0].path, near),
        (turn, param(turn).expect("registered").get(&params)),
    ];
    let f = Fit {
        params,
        ..ended_at(&c, vec![], values)
    };
    let sp = spread(&target, &f, 1.0);
    assert_eq!(sp[0].value, near, "{sp:?}");
}

/// A fit of `c`, with `carried`, that ended at `values` (no simulation behind it).
pub(crate) fn ended_at(
    c: &Candidate,
    carried: Vec<Fitted>,
    values: Vec<(&'static str, f64)>,
) -> Fit {
    Fit {
        candidate: c.clone(),
        carried,
        name: c.name(),
        params: Params::default(),
        values,
        chi2: 1.0,
        objective: 1.0,
        gap: 1.0,
        signal_gaps: Vec::new(),
        record_chi2: Vec::new(),
    }
}

/// A recalibration starts at its known value, the middle of its bounds, where the
/// optimiser's first trust region was 1e-13 wide (`Z_OFFSET`): the bulk modulus on
/// seed 1's steps with form error and nothing hidden stayed at exactly 1.7e9 (gap
/// 2.281) while 1.68e9 gives 2.175 (measured). It must move there.
#[test]
fn a_fit_started_at_the_middle_of_its_bounds_moves() {
    use crate::gap::blind::Setup;
    use crate::gap::hide::Kind;
    use crate::gap::recalibrate;
    use crate::gap::tests::record;
    use crate::gap::variants::Simulator;

    let s = Setup::new(Simulator::Rust, true, &[], 1);
    let records = [record(&s, Kind::Steps, 1)];
    let target = crate::gap::target_of(&records).expect("a target");
    let bulk = recalibrate::candidates(&s.known, 0.15, &[])
        .into_iter()
        .find(|c| c.name() == "fluid.bulk_modulus")
        .expect("the bulk modulus is recalibrated");
    let known = param("fluid.bulk_modulus")
        .expect("registered")
        .get(&s.known);
    let f = fit(&target, &s.known, &bulk, &[]);
    let moved = f.values[0].1 / known - 1.0;
    // -1.5 %, gap 2.281 -> 2.17 (measured)
    assert!(moved < -0.005, "{:?}", f.values);
    assert!(
        f.gap < 0.97 * target.gap(&s.known),
        "{} against {}",
        f.gap,
        target.gap(&s.known)
    );
}

/// On a record holding no valve lag the valve lag's fit seeks the static valve, a spool
/// faster than any D765: before the fit's bounds (`effects::FASTEST_SPOOL`,
/// `LEAST_SPOOL_DAMPING`) it went to the registry's 20000 rad/s with a damping of 0.1,
/// 1 s of CPU a simulation, and cost most of an analysis (measured on the 2 s chirp).
/// Now a bound of its fit stops it, and a fit stopped there is no candidate.
#[test]
fn a_valve_lag_fitted_where_there_is_none_is_stopped_by_the_fastest_d765() {
    use crate::gap::blind::Setup;
    use crate::gap::effects::candidate;
    use crate::gap::hide::Kind;
    use crate::gap::tests::record;
    use crate::gap::variants::Simulator;

    let s = Setup::new(Simulator::Rust, true, &[], 1);
    let records = [record(&s, Kind::Steps, 1)];
    let target = crate::gap::target_of(&records).expect("a target");
    let lag = candidate(Effect::ValveDynamics).expect("a candidate");
    let f = fit(&target, &s.known, &lag, &[]);
    let stopped = f.on_bound();
    assert!(
        stopped.is_some_and(|(p, _)| p == "sv1.natural_frequency" || p == "sv1.damping"),
        "{:?} gap {} against {}",
        f.values,
        f.gap,
        target.gap(&s.known)
    );
}

/// The fits stop where a step changes the misfit by less than the simulations'
/// tolerance (`optimiser`): a smaller change is the integrator's noise. What must hold
/// is that the looser stop ends at as good a fit as one simulated and stopped at 1e-6.
/// A valve lag hidden in the chirp is the slowest of the bench's fits to settle (up to
/// 131 simulations, session 23) and its valley is flat: the two fits' natural
/// frequencies are 1 % apart (2404 and 2380 rad/s) at misfits 5e-5 apart (measured), so
/// the misfit is what is compared: stopping at 1e-3 ends 2.5e-3 above the tight fit's
/// misfit, and this test fails (measured). Since session 61's noise estimate weighs this
/// record's P1 a third more, the looser fit stopped on its coordinates' step half-way
/// down the valley (2983 against 2370 rad/s, 2.3e-3 above); it passes because such a fit
/// is started once more (`fit::minimised`).
#[test]
fn a_fit_stopped_at_its_simulation_tolerance_ends_as_well_as_a_tighter_fit() {
    use crate::gap::blind::Setup;
    use crate::gap::effects::candidate;
    use crate::gap::evidence::SAME_VALUE;
    use crate::gap::hide::Kind;
    use crate::gap::tests::record;
    use crate::gap::variants::Simulator;
    use crate::gap::{at_rtol, RTOL};
    /// The tolerance the workflow simulated and stopped at before session 23.
    const TIGHT: f64 = 1e-6;

    let s = Setup::new(Simulator::Rust, true, &[Effect::ValveDynamics], 1);
    let records = [record(&s, Kind::Chirp, 1)];
    let target = crate::gap::target_of(&records).expect("a target");
    let lag = candidate(Effect::ValveDynamics).expect("a candidate");
    let loose = fit(&target, &at_rtol(&s.known, RTOL), &lag, &[]);
    let tight = fit(&target, &at_rtol(&s.known, TIGHT), &lag, &[]);
    const { assert!(RTOL > TIGHT, "the workflow's tolerance is the looser one") };
    // the looser fit's parameters simulated as tightly as the other fit's: what is left
    // of the gap between them is where the looser fit stopped, not its simulations
    let stopped = target.gap(&at_rtol(&loose.params, TIGHT));
    assert!(
        (stopped / tight.gap - 1.0).abs() < SAME_VALUE,
        "gap {stopped} against {} ({:?} against {:?})",
        tight.gap,
        loose.values,
        tight.values
    );
}

/// A fit starts from the screen's lowest point and from its lowest other local minimum:
/// one start on a profile with one valley, two on one with two (the first of equals, in
/// screening order), and a flat profile gives its first point.
#[test]
fn a_screen_with_two_valleys_gives_two_starts() {
    assert_eq!(screen::basins(&[5.0, 3.0, 1.0, 2.0, 4.0]), vec![2]);
    assert_eq!(screen::basins(&[2.0, 3.0, 1.0, 2.0, 4.0]), vec![2, 0]);
    assert_eq!(screen::basins(&[1.0, 1.0, 1.0, 1.0, 1.0]), vec![0]);
    assert_eq!(
        screen::basins(&[3.0, 2.0, 4.0, 1.0, 5.0, 0.5, 6.0]),
        vec![5, 3]
    );
    // a parameter of either sign: -hi .. -lo, lo .. hi, one valley at the small magnitudes
    assert_eq!(
        screen::basins(&[9.0, 7.0, 5.0, 3.0, 2.0, 2.1, 4.0, 6.0]),
        vec![4]
    );
}

/// A fit started from the fit of a question it contains (one more parameter carried,
/// at the model's value there) ends at or below that fit and moves the new parameter:
/// what lets a widened question start from the plain one alone (`fit_from`,
/// `decision::Start::Only`). The oil mass's form error leaves the viscous friction off
/// its built-in 400 N s/m.
#[test]
fn a_fit_started_from_a_question_it_contains_ends_at_or_below_it() {
    use crate::gap::blind::Setup;
    use crate::gap::effects::candidate;
    use crate::gap::hide::Kind;
    use crate::gap::recalibrate;
    use crate::gap::tests::record;
    use crate::gap::variants::Simulator;

    let s = Setup::new(Simulator::Rust, true, &[Effect::ManifoldInertia], 1);
    let records = [record(&s, Kind::Steps, 1)];
    let target = crate::gap::target_of(&records).expect("a target");
    let viscous = recalibrate::candidates(&s.known, 0.15, &[])
        .into_iter()
        .find(|c| c.name() == "actuator.viscous_friction")
        .expect("the viscous friction is on");
    let c = candidate(Effect::ManifoldInertia).expect("a candidate");
    let plain = fit(&target, &s.known, &c, &[]);
    let wider = fit_from(&target, &s.known, &c, &viscous.fitted, &plain.params);
    assert!(
        wider.chi2 <= plain.chi2,
        "{} against {}",
        wider.gap,
        plain.gap
    );
    let path = "actuator.viscous_friction";
    let at = |p: &Params| param(path).expect("registered").get(p);
    assert!(
        (at(&wider.params) / at(&plain.params) - 1.0).abs() > 1e-3,
        "{} unmoved",
        at(&wider.params)
    );
    assert_eq!(at(&plain.params), at(&s.known), "the plain fit left it");
}

/// `--record-variance own`: two steps records of one bench, the position sensor swapped for
/// a slower one between them (`holdout::tests::an_effect_one_record_alone_demands_is_refused`): the plain
/// record sits at its noise under the known model, the delayed one far off. Each record
/// weighs by its misfit (`Problem::weighed`): the plain one by its noise, the other by
/// its gap. The joint delay then bends the plain record less than a fit of the pooled
/// chi-square does, and ends lower on the likelihood with one variance per record,
/// sum_r N_r ln chi2_r, which the weights approach. Measured: weights 0.164 and 1; the
/// plain record's chi-square 8977 weighted against 19807 pooled, the delayed one's 34845
/// against 19309.
#[test]
fn a_joint_fit_weighs_each_record_by_its_misfit() {
    use crate::gap::blind::Setup;
    use crate::gap::effects::candidate;
    use crate::gap::hide::Kind;
    use crate::gap::tests::record;
    use crate::gap::variants::Simulator;

    let delayed = Setup::new(Simulator::Rust, false, &[Effect::SensorDelay], 2);
    let plain = Setup::new(Simulator::Rust, false, &[], 2);
    let records = [
        record(&delayed, Kind::Steps, 2),
        record(&plain, Kind::Steps, 3),
    ];
    let mut target = crate::gap::target_of(&records).expect("a target");
    let known = &plain.known;
    // pooled, the default, weighs every sample against its noise alone
    assert!(target.weights(known).is_empty());
    assert_eq!(target.misfit(known).expect("simulates").0.records.len(), 1);
    target.variance = Variance::Own;
    let w = target.weights(known);
    assert_eq!(w.len(), 2);
    assert!(w[0] < 0.5 && w[1] == 1.0, "weights {w:?}");
    let delay = candidate(Effect::SensorDelay).expect("a candidate");
    let weighted = fit(&target, known, &delay, &[]);
    // the same fit of the pooled chi-square, from the same start
    let mut pooled = unweighed(&target, known, &delay, &[]);
    pooled.at(pooled.coordinates_of(&weighted.params));
    let (pooled, _) = optimiser(known.solver.rtol).minimize(pooled);
    let pooled = ended(&pooled, &delay, &[]);
    let profile = |f: &Fit| -> f64 {
        f.record_chi2
            .iter()
            .zip(&target.records)
            .map(|(c, r)| r.len() as f64 * c.ln())
            .sum()
    };
    assert!(
        profile(&weighted) < profile(&pooled),
        "{} against {}",
        profile(&weighted),
        profile(&pooled)
    );
    eprintln!(
        "weights {w:?}; chi2 by record {:?} weighted, {:?} pooled",
        weighted.record_chi2, pooled.record_chi2
    );
    assert!(
        weighted.record_chi2[1] < pooled.record_chi2[1],
        "the plain record: {:?} weighted against {:?} pooled",
        weighted.record_chi2,
        pooled.record_chi2
    );
    // the noise-normalised figures are the records' own, the weights divided out
    assert!((weighted.record_chi2.iter().sum::<f64>() / weighted.chi2 - 1.0).abs() < 1e-12);
    assert!(weighted.objective < weighted.chi2);
}
