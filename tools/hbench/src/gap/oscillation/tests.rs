use std::collections::BTreeMap;
use std::f64::consts::PI;

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use super::super::data::Measured;
use super::super::drive::Traces;
use super::{find, Oscillation};

/// Pressure noise of the DS1104-like acquisition the blind studies draw (Pa).
const NOISE: f64 = 0.13e5;
const PERIOD: f64 = 1e-3;
const SAMPLES: usize = 1000;

/// A 1 s record of a slow move: P1 and P2 follow a ramp, with white noise on the measured
/// signals, and `extra(t)` added to the measured P1 (the simulated one gets
/// `extra_sim(t)`).
fn record(extra: impl Fn(f64) -> f64, extra_sim: impl Fn(f64) -> f64) -> (Measured, Traces) {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let normal = Normal::new(0.0, NOISE).expect("a normal law");
    let time: Vec<f64> = (0..SAMPLES).map(|k| k as f64 * PERIOD).collect();
    let p1: Vec<f64> = time.iter().map(|t| 100e5 + 20e5 * t).collect();
    let p2: Vec<f64> = time.iter().map(|t| 100e5 - 20e5 * t).collect();
    let y: Vec<f64> = time.iter().map(|t| 0.01 * t).collect();
    let mut columns = BTreeMap::new();
    let mut noisy =
        |x: &[f64]| -> Vec<f64> { x.iter().map(|v| v + normal.sample(&mut rng)).collect() };
    let p1m: Vec<f64> = noisy(&p1)
        .iter()
        .zip(&time)
        .map(|(v, t)| v + extra(*t))
        .collect();
    columns.insert("P1".to_string(), p1m);
    columns.insert("P2".to_string(), noisy(&p2));
    columns.insert("y".to_string(), y.clone());
    let mut signals = BTreeMap::new();
    let p1s: Vec<f64> = p1
        .iter()
        .zip(&time)
        .map(|(v, t)| v + extra_sim(*t))
        .collect();
    signals.insert("P1", p1s);
    signals.insert("P2", p2);
    signals.insert("y", y);
    (
        Measured {
            time: time.clone(),
            columns,
        },
        Traces { time, signals },
    )
}

fn sine(f: f64, rms: f64) -> impl Fn(f64) -> f64 {
    move |t| rms * 2f64.sqrt() * (2.0 * PI * f * t + 0.3).sin()
}

fn quiet(_: f64) -> f64 {
    0.0
}

/// The window of the moves record where the seed-1 bench oscillated: 0.625-0.75 s.
fn window() -> std::ops::Range<usize> {
    625..750
}

fn found(m: &Measured, s: &Traces) -> Option<Oscillation> {
    find(m, s, window(), NOISE * 2f64.sqrt())
}

/// A record of known oscillation: 212 Hz at 3 bar RMS in the measured load pressure, none
/// in the simulated. Its frequency is read within 1 % and its size within 5 % from the
/// 125 samples of one window, and the model is said to lack it.
#[test]
fn an_oscillation_the_model_lacks_is_found_at_its_frequency() {
    for f in [45.0, 212.0, 330.0] {
        let (m, s) = record(sine(f, 3e5), quiet);
        let o = found(&m, &s).unwrap_or_else(|| panic!("{f} Hz not found"));
        assert_eq!(o.signal, "P1 - P2");
        assert!(
            (o.frequency_hz / f - 1.0).abs() < 0.01,
            "{f} Hz read as {o:?}"
        );
        assert!((o.measured_rms / 3e5 - 1.0).abs() < 0.05, "{o:?}");
        assert!(o.simulated_rms < 0.1 * o.measured_rms, "{o:?}");
        assert!(o.share > 0.9, "{o:?}");
        assert!((o.start - 0.625).abs() < 1e-9 && (o.end - 0.749).abs() < 1e-9);
    }
}

/// Noise alone, an oscillation the model has as well, and one too small to tell from
/// the noise are no oscillation the model lacks; nor is a broadband misfit (the simulated
/// pressure lagging the measured one's slow ripple by a phase that leaves a residual of
/// every frequency: a decaying exponential).
#[test]
fn noise_a_shared_oscillation_and_broadband_misfit_are_not_reported() {
    let (m, s) = record(quiet, quiet);
    assert!(found(&m, &s).is_none(), "noise alone: {:?}", found(&m, &s));
    let (m, s) = record(sine(212.0, 3e5), sine(212.0, 3e5));
    assert!(found(&m, &s).is_none(), "shared: {:?}", found(&m, &s));
    let (m, s) = record(sine(212.0, 0.5 * NOISE), quiet);
    assert!(
        found(&m, &s).is_none(),
        "below the noise: {:?}",
        found(&m, &s)
    );
    let kick = |t: f64| {
        if t >= 0.625 {
            5e5 * (-(t - 0.625) / 0.004).exp()
        } else {
            0.0
        }
    };
    let (m, s) = record(kick, quiet);
    assert!(
        found(&m, &s).is_none(),
        "a decaying kick: {:?}",
        found(&m, &s)
    );
}
