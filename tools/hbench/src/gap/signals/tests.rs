use hbmodel::effects::Effect;

use super::super::blind::Setup;
use super::super::fit::fit;
use super::super::hide::Kind;
use super::super::recalibrate::{self, DEFAULT_FRACTION};
use super::super::target_of;
use super::super::tests::{pressures_lagging, record};
use super::super::variants::Simulator;
use super::{describe, per_signal, Baseline, SignalGap};

/// The signals' gaps are the record's gap split by signal: their mean square, weighed by
/// samples, is the record's mean square, before and after. A manifold volume hidden on
/// the steps (no form error) and put into the model moves every signal closer to the
/// data, none further: nothing is traded.
#[test]
fn a_missing_volume_put_in_brings_every_signal_closer() {
    let s = Setup::new(Simulator::Rust, false, &[Effect::ManifoldVolume], 1);
    let records = [record(&s, Kind::Steps, 1)];
    let target = target_of(&records).expect("a target");
    let names = vec!["steps".to_string()];
    let signals = per_signal(&target, &names, &s.known, &s.bench.params);
    assert_eq!(signals.len(), 3, "{signals:?}");
    let before: Vec<f64> = signals.iter().map(|g| g.before).collect();
    let after: Vec<f64> = signals.iter().map(|g| g.after).collect();
    for (model, gap) in [(&s.known, before), (&s.bench.params, after)] {
        let mean_square = gap.iter().map(|g| g * g).sum::<f64>() / 3.0;
        let whole = target.gap(model);
        assert!(
            (mean_square.sqrt() / whole - 1.0).abs() < 1e-12,
            "{mean_square} against {whole}"
        );
    }
    assert!(signals.iter().all(|g| !g.worse()), "{signals:?}");
    assert!(signals.iter().any(|g| g.better()), "{signals:?}");
    assert!(!describe(&signals, "manifold_volume").contains("further"));
}

/// A first-order lag of the pressure sensors (0.4 ms, the form error's range, no
/// candidate) taken up by the workflow's own bulk-modulus recalibration: the oil comes
/// out softer and the pressures closer to the data, and the position is taken away from
/// its record, which the report names as a trade that may stand for the sensors' own
/// dynamics (measured: y 0.842 -> 0.895, P1 8.20 -> 5.33, P2 8.24 -> 5.27). Until
/// session 63 `hide` ran the lag on the 1 kHz samples held at their new value, which
/// made 0.4 ms act as about 0.1 ms: the pressures were then 2.13 noise levels off, the
/// position did not move (0.8389 -> 0.8391) and the trade could not be seen.
#[test]
fn a_pressure_lag_taken_up_as_softer_oil_takes_the_position_away() {
    let s = pressures_lagging(0.4e-3);
    let known = &s.known;
    let records = [record(&s, Kind::Steps, 1)];
    let target = target_of(&records).expect("a target");
    let softer = recalibrate::candidates(known, DEFAULT_FRACTION, &[])
        .into_iter()
        .find(|c| c.fitted.iter().any(|f| f.path == "fluid.bulk_modulus"))
        .expect("the bulk modulus is recalibrated");
    let f = fit(&target, known, &softer, &[]);
    let bulk = f.values[0].1 / known.fluid.bulk_modulus;
    assert!(
        bulk < 0.99,
        "the bulk modulus fitted at {bulk} of its known value"
    );
    let signals = per_signal(&target, &["steps".to_string()], known, &f.params);
    let moved = |g: &SignalGap| (g.worse(), g.better());
    let by: Vec<(&str, (bool, bool))> = signals.iter().map(|g| (g.signal, moved(g))).collect();
    assert_eq!(
        by,
        vec![
            ("y", (true, false)),
            ("P1", (false, true)),
            ("P2", (false, true))
        ],
        "{signals:?}"
    );
    let text = describe(&signals, "fluid.bulk_modulus");
    assert!(text.contains("It took y further from the data"), "{text}");
    assert!(text.contains("a lag of the pressure sensors"), "{text}");
}

/// The peer's steps with nothing hidden (seed 2, 0.31 ms pressure lag): the manifold
/// volume added took the position away from the data and brought the pressures closer
/// (gaps as measured, session 25), and the report says so; one record's signals go
/// without its name, two records' with it.
#[test]
fn a_step_that_trades_the_position_for_the_pressures_is_called_so() {
    let gap = |record: &str, signal, before, after| SignalGap {
        record: record.into(),
        signal,
        before,
        after,
    };
    let peer = [
        gap("steps", "y", 1.758, 1.822),
        gap("steps", "P1", 18.4, 16.1),
        gap("steps", "P2", 19.7, 17.2),
    ];
    let text = describe(&peer, "manifold_volume");
    assert!(
        text.starts_with("By signal: y 1.76 -> 1.82, P1 18.40 -> 16.10"),
        "{text}"
    );
    assert!(
        text.contains("It took y further from the data while it brought P1, P2 closer"),
        "{text}"
    );
    assert!(
        text.contains(
            "`manifold_volume` may stand in part for something that acts on P1, P2 alone"
        ),
        "{text}"
    );
    assert!(text.contains("a lag of the pressure sensors"), "{text}");
    // within the 1 % a step must bring, a signal's rise is the fit's give and take
    let even = [
        gap("steps", "y", 1.758, 1.770),
        gap("steps", "P1", 18.4, 16.1),
    ];
    assert!(!describe(&even, "manifold_volume").contains("further"));
    let two = [gap("sweep", "y", 2.0, 1.0), gap("steps", "y", 2.0, 1.0)];
    assert!(describe(&two, "payload").contains("sweep y 2.00 -> 1.00, steps y"));
}

/// Each candidate of a round is read for trades from its own fit (`Fit::signal_gaps`,
/// the optimiser's last residual, no simulation more), against the model the round
/// starts from. On seed 2's steps with form error (a 0.46 ms lag of the pressure
/// sensors) and a hidden dry friction of 27.6 N, the dry friction's own fit is bent to
/// the pressures' lag (209 N, its Stribeck velocity on its bound) and takes the position
/// away from its record (y 1.37 -> 1.79, measured): a trade, named with its figures, though
/// the effect is the one hidden. So a trade is reported and not judged (the module's
/// words). The bulk modulus's recalibration trades the position too (y 1.37 -> 1.40,
/// measured since session 63, when `hide`'s lag became the 0.46 ms it names; before, it
/// acted as 0.13 ms and the recalibration traded nothing). The fit's own signal gaps are
/// `per_signal`'s.
#[test]
fn even_the_hidden_effect_trades_the_position_under_a_pressure_lag() {
    let s = Setup::new(Simulator::Rust, true, &[Effect::DryFriction], 2);
    let known = &s.known;
    let records = [record(&s, Kind::Steps, 2)];
    let target = target_of(&records).expect("a target");
    let names = ["steps".to_string()];
    let before = Baseline::of(&target, &names, known);
    let dry = super::super::effects::candidate(Effect::DryFriction).expect("a candidate");
    let bent = fit(&target, known, &dry, &[]);
    let signals = per_signal(&target, &names, known, &bent.params);
    for (g, own) in signals.iter().zip(&bent.signal_gaps) {
        assert!((g.after / own - 1.0).abs() < 1e-9, "{signals:?} {own}");
    }
    let trade = before.traded(&bent.signal_gaps);
    assert!(
        trade.as_deref().is_some_and(|t| t.starts_with("y ")),
        "{trade:?} {signals:?}"
    );
    let softer = recalibrate::candidates(known, DEFAULT_FRACTION, &[])
        .into_iter()
        .find(|c| c.fitted.iter().any(|f| f.path == "fluid.bulk_modulus"))
        .expect("recalibrated");
    let softer = fit(&target, known, &softer, &[]);
    let trade = before.traded(&softer.signal_gaps);
    assert!(
        trade.as_deref().is_some_and(|t| t.starts_with("y ")),
        "{trade:?}"
    );
}

/// The position's evidence reads the position alone: two records' y series, each in its
/// samples, against the independent samples the position's residual is worth; the
/// pressures, however far off, weigh nothing in it.
#[test]
fn the_position_is_judged_on_its_own_series() {
    let label = |r: &str, s: &'static str| (r.to_string(), s);
    let before = Baseline {
        labels: vec![
            label("steps", "y"),
            label("steps", "P1"),
            label("chirp", "y"),
            label("chirp", "P1"),
        ],
        gaps: vec![2.0, 8.0, 1.0, 8.0],
        lens: vec![300, 300, 100, 100],
        position_effective: 40.0,
    };
    // y's chi-square 300 * 1 + 100 * 1 against 300 * 4 + 100 * 1: ln B = 20 ln(1300/400)
    let a = [1.0, 8.0, 1.0, 1.0];
    let b = [2.0, 1.0, 1.0, 1.0];
    let ln_b = before.position_ln_bayes(&a, &b) / 2.0;
    assert!(
        (ln_b - 20.0 * (1300.0f64 / 400.0).ln()).abs() < 1e-9,
        "{ln_b}"
    );
    assert!((before.position_ln_bayes(&b, &a) + 2.0 * ln_b).abs() < 1e-9);
    assert_eq!(before.position_ln_bayes(&a, &b[..3]), 0.0);
    assert!(before.position_within(&a, 1.1));
    assert!(!before.position_within(&[1.0, 0.5, 1.2, 0.5], 1.1));
    assert!(!before.position_within(&a[..2], 1.1));
}
