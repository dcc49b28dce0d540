//! Chapter 4's story told by the tool: the model without the manifold misses the
//! bench's resonance; the workflow sees the shift and names the manifold's volume and
//! inertia.

use super::super::hide::measure;
use super::*;
use hbmodel::Mode;

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
    let (experiment, measured) = measure(&bench, Kind::Sweep, 4).unwrap();
    let o = super::super::run(&known, &experiment, &measured, false).unwrap();
    // the passages come in first, as a whole: with the losses (which bring the
    // volume and inertia along) fitted near none, or volume and inertia one by one
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
