//! Chapter 4's story told by the tool: the model without the manifold misses the
//! bench's resonance; the workflow sees the shift and names the manifold's volume and
//! inertia.

use super::super::experiments::Design;
use super::super::hide::measure_under;
use super::*;
use hbmodel::Mode;

/// The story's sweep: 1-300 Hz as in the standard design, over STORY_SWEEP s instead of
/// 2.5 s, which cuts the cost of CI's longest test in proportion. Measured on this
/// bench (seed 4): the measured resonance reads 232.9 Hz with damping 0.057 on 1.5 s
/// against 232.5 Hz and 0.054 on 2.5 s; on 1.0 and 1.25 s the bump is too short-lived
/// for the estimator (no resonance found).
const STORY_SWEEP: f64 = 1.5;

/// The story ends once the passages' two effects are in (`Settings::max_effects`). Run
/// on, the workflow named the volume (gap 61.7 -> 1.62) and the oil mass (1.16), then
/// re-fitted the valve's natural frequency (1.02) and the sensor delay (1.006): rounds of
/// every candidate simulated with the passages' fast oil columns, which took the test
/// from 186 CPU s to 970 (measured, session 31; 392 in session 19).
const STORY_EFFECTS: usize = 2;

#[test]
fn the_missing_manifold_is_named_from_the_resonance_shift() {
    let mut known = Params::thesis_bench(Mode::ThreeWay);
    let manifold = [
        Effect::ManifoldVolume,
        Effect::ManifoldInertia,
        Effect::ManifoldLosses,
    ];
    for e in manifold {
        known.effects.set(e, false);
    }
    // the bench: the thesis's passages (Tables 3.3, 3.4), losses aside
    let mut bench = known.clone();
    bench.effects.set(Effect::ManifoldVolume, true);
    bench.effects.set(Effect::ManifoldInertia, true);
    let design = Design {
        duration: STORY_SWEEP,
        ..Design::standard(Kind::Sweep)
    };
    let (experiment, measured) = measure_under(&bench, &design, 4).unwrap();
    let record = super::super::Record {
        name: "story".into(),
        experiment,
        measured,
    };
    let o = super::super::run_with(
        &known,
        std::slice::from_ref(&record),
        super::super::Settings {
            max_effects: STORY_EFFECTS,
            ..study()
        },
    )
    .unwrap();
    // the passages come in first, as a whole: with the losses (which bring the
    // volume and inertia along) fitted near none, or volume and inertia one by one;
    // with STORY_EFFECTS 2 the run adds no third effect, so both must be among its two
    let steps: Vec<_> = o
        .steps
        .iter()
        .map(|s| (s.name.as_str(), &s.brings, &s.parameters))
        .collect();
    let first = o.steps.first().expect("an effect is named");
    assert!(first.name.starts_with("manifold_"), "{steps:?}");
    assert!(
        manifold[..2].iter().all(|e| o.model.has(*e)),
        "the passages' volume and inertia are in the fitted model: {steps:?}"
    );
    // at the thesis's size: the oil mass fitted cold beside the volume stopped at half
    // of it on the 2.5 s sweep, until its fit also started from where the losses' joint
    // candidate of the round before had fitted both (`selection::fit_all`, session 39)
    for (name, scale) in [
        ("volume", o.model.manifold.volume_scale),
        ("oil mass", o.model.manifold.inertia_scale),
    ] {
        assert!(
            (0.75..1.25).contains(&scale),
            "the passages' {name} at the truth's scale 1 within 25 %: {scale} {steps:?}"
        );
    }
    if o.model.has(Effect::ManifoldLosses) {
        let losses = o.model.manifold.loss_scale;
        assert!(losses < 0.25, "the bench has no losses: {losses} {steps:?}");
    }
    let r = o.records[0]
        .first
        .resonance
        .clone()
        .expect("the sweep shows a resonance");
    assert!((150.0..250.0).contains(&r.measured_hz), "{r:?}");
    assert!(r.simulated_hz > r.measured_hz + 25.0, "{r:?}");
    assert!(
        o.remaining_gap < 0.1 * o.initial_gap,
        "{} -> {}",
        o.initial_gap,
        o.remaining_gap
    );
}
