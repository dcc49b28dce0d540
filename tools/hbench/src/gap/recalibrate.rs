//! Recalibration beside missing effects (issue 14, item 4): the known model's uncertain
//! parameters, re-fitted within bounds, compete with the candidate effects. A bench whose
//! oil is 7 % stiffer than the model's is then told as a recalibration of the bulk
//! modulus, not as entrained air; an effect that is on but far off its true size (an
//! internal leakage 300 times the thesis's) as a recalibration of that effect.

use hbmodel::effects::Effect;
use hbmodel::params::param;
use hbmodel::Params;

use super::effects::{candidate, Candidate, Fitted, StepKind};

/// Default half-width of the recalibration bounds of the base model's parameters, as a
/// fraction of the known value: a measured bulk modulus, mass, valve rated flow or dead
/// volume is rarely more than a few percent off (issue 14: "a few percent"); 15 % leaves
/// room for twice that. `hbench gap --recalibrate-within` sets it.
pub const DEFAULT_FRACTION: f64 = 0.15;

/// The base model's parameters a bench record can contradict, re-fitted one at a time.
/// SV2 follows SV1 unless `valve_asymmetry` is on (then it has its own rated flow there).
const BASE: [(&str, &str); 4] = [
    (
        "fluid.bulk_modulus",
        "stiffer or softer oil: every hydraulic resonance moves, in proportion to its root",
    ),
    (
        "actuator.mass",
        "heavier or lighter moving parts: the mechanical resonance moves, the loads change",
    ),
    (
        "sv1.rated_flow",
        "valve gain off: the loop's speed and the pressure swings scale together",
    ),
    (
        "actuator.dead_volume",
        "more or less oil between valve and piston: the resonance moves, more at the ends",
    ),
];

/// Base parameters whose known value is zero, re-fitted within an absolute band.
/// The valves' null bias: a servovalve's hydraulic null drifts by up to a few percent of
/// rated input and is trimmed on the bench (MOOG's null adjust); +-0.3 V is 3 % of the
/// D765's 10 V, the top of the plausible range `valve_asymmetry` draws SV2's bias from.
/// In mode 3 a bias common to both valves moves both chamber pressures' null level
/// together (the peer bench's edge overlaps put it 2.4 bar under ours, measured); SV2
/// follows SV1's bias unless `valve_asymmetry` is on.
const ABSOLUTE: [(&str, f64, &str); 1] = [(
    "sv1.null_bias",
    0.3,
    "the valves' hydraulic null off their zero command: both chamber pressures rest higher or lower, the loop holds a small standing error",
)];

/// SV2 against SV1, while `valve_asymmetry` is off (SV2 then copies SV1): two valves of
/// one type, each within a few percent of its catalogue flow (the form error draws +-5 %
/// each), differ in flow by up to 10 %, and their hydraulic nulls by a few hundredths of
/// a volt (0.5 % of rated input; `valve_asymmetry` draws SV2's bias from 0.05 V up).
/// Fitting them turns SV2 into its own valve, equal to SV1 but for these two; a larger
/// bias or gain difference stays the `valve_asymmetry` effect's. On the peer bench, whose
/// SV2 is drawn apart from SV1, `valve_asymmetry` was named first on every record with
/// model-form error (SV2 bias 0.014 V, flow +8 %; measured, 2026-11-23).
pub const SV2_FLOW: (&str, f64) = ("sv2.rated_flow", 0.10);
pub const SV2_BIAS: (&str, f64) = ("sv2.null_bias", 0.05);
const SV2_FLOW_AND_BIAS: [&str; 2] = [SV2_FLOW.0, SV2_BIAS.0];

/// SV1's parameters that SV2 shares even as its own valve: the workflow fits SV2 apart
/// only in flow and null bias (above, and `valve_asymmetry`), so what a record says of the
/// spool's lands and dynamics it says of both valves of one type (the peer's two valves
/// share them too, `variants`). Without the tie, SV2 kept the null leakage it was copied
/// with when its recalibration made it its own valve: on the peer's slow moves with
/// nothing hidden (seed 1, form error) SV1's later null leakage recalibration went
/// 1.33e-12 -> 8.3e-13 m3/(s Pa) alone, the manifold's volume (1.77 times Table 3.3)
/// made up the rest, and the run ended at 4.83; with SV2's null leakage following, the
/// run takes the two recalibrations and nothing else, 34.33 -> 10.67 -> 4.43 (measured,
/// session 33). The Rust bench's form error draws SV1's null leakage alone (+-20 %,
/// `variants`), so with `valve_asymmetry` hidden its valves' lands differ, and its runs
/// now end 0.2-1.3 noise levels higher, the asymmetry still fitted within 3 %.
const SHARED_BY_SV2: [(&str, &str); 5] = [
    ("sv1.null_leakage", "sv2.null_leakage"),
    ("sv1.null_width", "sv2.null_width"),
    ("sv1.natural_frequency", "sv2.natural_frequency"),
    ("sv1.damping", "sv2.damping"),
    ("sv1.max_spool_rate", "sv2.max_spool_rate"),
];

/// Set the fitted parameter `path` of `p` to `value`, and SV2's twin of it when SV2 is its
/// own valve and shares it (`SHARED_BY_SV2`); when it is not, SV2 copies SV1 anyway.
pub fn set_fitted(p: &mut Params, path: &str, value: f64) {
    param(path).expect("registered").set(p, value);
    if !p.has(Effect::ValveAsymmetry) {
        return;
    }
    if let Some((_, twin)) = SHARED_BY_SV2.iter().find(|(sv1, _)| *sv1 == path) {
        param(twin).expect("registered").set(p, value);
    }
}

/// A parameter re-fitted within `bounds`, screened over the same span.
fn within(path: &'static str, bounds: [f64; 2]) -> Fitted {
    Fitted {
        path,
        plausible: bounds,
        log: false,
        either_sign: false,
        bounds: Some(bounds),
        drawn: true,
        floor_accepted: false,
    }
}

/// A recalibration of the base model's parameters `fitted`.
fn recalibration(fitted: Vec<Fitted>, signature: &'static str) -> Candidate {
    Candidate {
        kind: StepKind::Recalibrate,
        effect: None,
        fitted,
        signature,
        switches_on: &[],
    }
}

/// The recalibrations open in `model`: each base parameter within +-`fraction` of its
/// value (none when `fraction` is 0), and the parameters of each effect already on within
/// the registry's physical bounds; those in `done` (re-fitted in an earlier step, and
/// carried since) are left out.
pub fn candidates(model: &Params, fraction: f64, done: &[&str]) -> Vec<Candidate> {
    let mut out = if fraction > 0.0 {
        base(model, fraction, done)
    } else {
        Vec::new()
    };
    for e in model.effects.active() {
        let Some(c) = candidate(e) else { continue };
        if c.fitted.iter().any(|f| done.contains(&f.path)) {
            continue;
        }
        out.push(Candidate {
            kind: StepKind::Recalibrate,
            ..c
        });
    }
    out
}

/// The base model's recalibrations: relative, absolute, and SV2 against SV1.
fn base(model: &Params, fraction: f64, done: &[&str]) -> Vec<Candidate> {
    let mut out = Vec::new();
    for (path, signature) in BASE {
        if done.contains(&path) {
            continue;
        }
        let Some(spec) = param(path) else { continue };
        let v = spec.get(model);
        if !(v.is_finite() && v > 0.0) {
            continue;
        }
        let bounds = [
            (v * (1.0 - fraction)).max(spec.min),
            (v * (1.0 + fraction)).min(spec.max),
        ];
        out.push(recalibration(vec![within(path, bounds)], signature));
    }
    for (path, half, signature) in ABSOLUTE {
        let Some(spec) = param(path) else { continue };
        if done.contains(&path) {
            continue;
        }
        let v = spec.get(model);
        let bounds = [(v - half).max(spec.min), (v + half).min(spec.max)];
        out.push(recalibration(vec![within(path, bounds)], signature));
    }
    let sv2_open = !SV2_FLOW_AND_BIAS.iter().any(|p| done.contains(p));
    if sv2_open && !model.has(Effect::ValveAsymmetry) {
        let (flow, half_flow) = SV2_FLOW;
        let (bias, half_bias) = SV2_BIAS;
        let (q, b) = (model.sv1.rated_flow, model.sv1.null_bias);
        out.push(Candidate {
            switches_on: &[Effect::ValveAsymmetry],
            ..recalibration(
                vec![
                    within(flow, [q * (1.0 - half_flow), q * (1.0 + half_flow)]),
                    within(bias, [b - half_bias, b + half_bias]),
                ],
                "SV2 a few percent off SV1 (flow gain, null): the chambers fill at unequal rates, P2's rest level differs from P1's",
            )
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base_bounds_bracket_the_known_value_and_effects_on_are_offered() {
        let mut p = Params::default();
        p.effects.set(Effect::InternalLeakage, true);
        let c = candidates(&p, 0.1, &[]);
        let k = param("fluid.bulk_modulus").unwrap().get(&p);
        let bulk = c.iter().find(|c| c.name() == "fluid.bulk_modulus").unwrap();
        let [lo, hi] = bulk.fitted[0].bounds.unwrap();
        assert!((lo / k - 0.9).abs() < 1e-12 && (hi / k - 1.1).abs() < 1e-12);
        let leak = c
            .iter()
            .find(|c| c.effect == Some(Effect::InternalLeakage))
            .expect("an effect that is on can be recalibrated");
        assert_eq!(leak.kind, StepKind::Recalibrate);
        assert!(c.iter().all(|c| c.effect != Some(Effect::DryFriction)));
        let done = candidates(&p, 0.1, &["fluid.bulk_modulus", "sv1.null_leakage"]);
        assert_eq!(done.len(), c.len() - 2);
    }

    #[test]
    fn sv2_flow_is_a_recalibration_only_while_sv2_follows_sv1() {
        let mut p = Params::default();
        p.sv1.rated_flow = 3.0e-4;
        let c = candidates(&p, 0.15, &[]);
        let sv2 = c.iter().find(|c| c.name() == "sv2.rated_flow").unwrap();
        let [lo, hi] = sv2.fitted[0].bounds.unwrap();
        assert!((lo / 3.0e-4 - 0.9).abs() < 1e-12 && (hi / 3.0e-4 - 1.1).abs() < 1e-12);
        assert_eq!(sv2.fitted[1].bounds, Some([-0.05, 0.05]));
        p.effects.set(Effect::ValveAsymmetry, true);
        let c = candidates(&p, 0.15, &[]);
        assert!(c.iter().all(|c| c.name() != "sv2.rated_flow"));
    }

    #[test]
    fn sv2_as_its_own_valve_follows_sv1s_lands_and_spool_but_not_its_flow() {
        for (sv1, sv2) in SHARED_BY_SV2 {
            assert!(param(sv1).is_some() && param(sv2).is_some(), "{sv1} {sv2}");
        }
        let mut p = Params::default();
        p.effects.set(Effect::ValveAsymmetry, true);
        let (flow2, leak2) = (p.sv2.rated_flow, p.sv2.null_leakage);
        set_fitted(&mut p, "sv1.null_leakage", 0.3 * leak2);
        set_fitted(&mut p, "sv1.natural_frequency", 1500.0);
        set_fitted(&mut p, "sv1.rated_flow", 1.1 * flow2);
        assert_eq!(p.sv2.null_leakage, 0.3 * leak2);
        assert_eq!(p.sv2.natural_frequency, 1500.0);
        assert_eq!(
            p.sv2.rated_flow, flow2,
            "SV2's flow is its own once it is its own valve"
        );
        set_fitted(&mut p, "sv2.null_bias", 0.02);
        assert_eq!((p.sv1.null_bias, p.sv2.null_bias), (0.0, 0.02));
        // while SV2 copies SV1, the model reads SV1's: SV2's own field is left alone
        let mut q = Params::default();
        set_fitted(&mut q, "sv1.null_leakage", 0.3 * leak2);
        assert_eq!(q.sv2.null_leakage, leak2);
    }
}
