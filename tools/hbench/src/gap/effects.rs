//! The effects the workflow may add, with the registry parameters its fits adjust and the
//! range `hbench hide` draws them from. Bounds of the fits are the registry's physical
//! bounds; the plausible ranges are narrower: what a real bench of this kind would show.

use hbmodel::effects::{param, Effect};
use hbmodel::Params;
use serde::Serialize;

/// A parameter a candidate's fit adjusts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fitted {
    pub path: &'static str,
    /// What `hbench hide` draws from (a plausible bench), in the registry's unit.
    pub plausible: [f64; 2],
    /// Drawn and fitted on a log scale (quantities spanning decades).
    pub log: bool,
    /// The drawn value takes either sign (offsets).
    pub either_sign: bool,
    /// Bounds of the fit when narrower than the registry's physical bounds (a
    /// recalibration stays near the known value).
    pub bounds: Option<[f64; 2]>,
}

/// An effect the workflow can add, and what its missing shows in the data.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    pub effect: Effect,
    pub fitted: Vec<Fitted>,
    pub signature: &'static str,
}

const fn lin(path: &'static str, plausible: [f64; 2]) -> Fitted {
    Fitted {
        path,
        plausible,
        log: false,
        either_sign: false,
        bounds: None,
    }
}

const fn log(path: &'static str, plausible: [f64; 2]) -> Fitted {
    Fitted {
        path,
        plausible,
        log: true,
        either_sign: false,
        bounds: None,
    }
}

/// Temperature is an operating condition an experiment states, not missing physics: it is
/// never proposed. An unknown moving mass (`payload`) is.
pub fn candidate(e: Effect) -> Option<Candidate> {
    let (fitted, signature) = match e {
        // Table 3.3 volumes +-50 %: unknown passage details and hoses
        Effect::ManifoldVolume => (
            vec![lin("manifold.volume_scale", [0.6, 1.6])],
            "softer oil columns: the hydraulic resonance moves down, the loop lags more near it",
        ),
        Effect::ManifoldInertia => (
            vec![lin("manifold.inertia_scale", [0.6, 1.6])],
            "oil mass moving with the piston: a lower, sharper resonance",
        ),
        Effect::ManifoldLosses => (
            vec![lin("manifold.loss_scale", [0.5, 4.0])],
            "pressure drops growing with flow squared: slower fast moves, damped resonance",
        ),
        // 0.2-3 % free air at atmospheric pressure (appendix A)
        Effect::EntrainedAir => (
            vec![log("fluid.air_fraction", [0.002, 0.03])],
            "bulk modulus falling at low pressure: the resonance moves down, more at low chamber pressure",
        ),
        // a D765 leaks 0.5-3 L/min at null (catalogue; Fig. 2.10(a))
        Effect::InternalLeakage => (
            vec![log("sv1.null_leakage", [0.4e-12, 3e-12])],
            "flow between chambers and to tank at null: pressures sag, the loop is more damped, a load needs a standing error",
        ),
        // a few tens of newtons on hydrostatic bearings; 150 N for worn seals
        Effect::DryFriction => (
            vec![lin("friction.coulomb", [20.0, 150.0])],
            "a force of constant size against the motion: stick at reversals, small static errors",
        ),
        // 400 N.s/m in section 4.4; 150-2000 over oil temperature and bearing state
        Effect::ViscousFriction => (
            vec![log("actuator.viscous_friction", [150.0, 2000.0])],
            "force growing with speed: the resonance is damped, fast moves lag",
        ),
        // spool bandwidth 190-560 Hz at small signal (D765 catalogue, chapter 2)
        Effect::ValveDynamics => (
            vec![
                lin("sv1.natural_frequency", [1200.0, 3500.0]),
                lin("sv1.damping", [0.4, 0.9]),
            ],
            "a second-order lag of the flow: phase falling faster than a delay near the valve's bandwidth",
        ),
        // null bias of a few percent of rated input, flow gains +-15 %
        Effect::ValveAsymmetry => (
            vec![
                Fitted {
                    either_sign: true,
                    ..lin("sv2.null_bias", [0.05, 0.3])
                },
                lin("sv2.rated_flow", [2.7e-4, 3.6e-4]),
            ],
            "SV2 unlike SV1: a static offset of position and pressures, unequal gains in the two directions",
        ),
        // 0.2-2 ms between the physical signal and its sample (section 4.4: 0.5 ms)
        Effect::SensorDelay => (
            vec![lin("sensors.delay", [0.2e-3, 2e-3])],
            "phase lag growing linearly with frequency, no change of gain",
        ),
        // a fixture or tool of a few to a few tens of kilograms on the rod (the thesis's
        // payload is 20 kg)
        Effect::Payload => (
            vec![lin("actuator.payload_mass", [2.0, 60.0])],
            "more moving mass: the hydraulic resonance moves down, the position overshoots",
        ),
        Effect::Temperature => return None,
    };
    Some(Candidate {
        effect: e,
        fitted,
        signature,
    })
}

/// Every effect the workflow may propose, in registry order.
pub fn all() -> Vec<Candidate> {
    Effect::ALL.into_iter().filter_map(candidate).collect()
}

pub fn names() -> Vec<&'static str> {
    all().iter().map(|c| c.effect.name()).collect()
}

/// Whether a hypothesis adds an effect or re-fits parameters the model already has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    Add,
    Recalibrate,
}

/// What one fit tries: add an effect, or re-fit parameters of the known model.
#[derive(Debug, Clone, PartialEq)]
pub struct Hypothesis {
    pub kind: Kind,
    /// The registry effect added or re-fitted; None for the known model's own parameters.
    pub effect: Option<Effect>,
    pub fitted: Vec<Fitted>,
}

/// Name of the known model's own parameters (owned by no effect) in reports.
pub const KNOWN_MODEL: &str = "known_model";

impl Hypothesis {
    /// The effect's registry name, or KNOWN_MODEL.
    pub fn name(&self) -> &'static str {
        self.effect.map_or(KNOWN_MODEL, Effect::name)
    }

    /// A label naming the kind and what is fitted, e.g. `recalibrate fluid.bulk_modulus`.
    pub fn label(&self) -> String {
        match self.kind {
            Kind::Add => format!("add {}", self.name()),
            Kind::Recalibrate => format!(
                "recalibrate {}",
                self.fitted
                    .iter()
                    .map(|f| f.path)
                    .collect::<Vec<_>>()
                    .join(" + ")
            ),
        }
    }
}

/// The known model's uncertain parameters a recalibration may re-fit: the oil's
/// stiffness, the moving mass, the valves' rated flow and the chambers' dead volume.
pub const RECALIBRATED: [&str; 4] = [
    "fluid.bulk_modulus",
    "actuator.mass",
    "sv1.rated_flow",
    "actuator.dead_volume",
];

/// Default half-width of a recalibration's bounds, relative to the known value: a data
/// sheet or a thesis table is rarely more than 10-20 % off a bench's real value
/// (Table 1.1's bulk modulus stands for 1.4-1.8 GPa of mineral oil with a little air);
/// beyond that the known model is wrong in structure, not in value.
pub const RECALIBRATION_SPAN: f64 = 0.2;

/// Every candidate hypothesis on `model`: each registry effect not yet on (with what it
/// requires already on), then a recalibration of each uncertain known parameter and of
/// each active effect's parameters. `bounds` (path, [lo, hi]) replace the default bounds of
/// a recalibrated parameter.
pub fn hypotheses(model: &Params, bounds: &[(String, [f64; 2])]) -> Vec<Hypothesis> {
    let bounded = |f: Fitted| Fitted {
        bounds: bounds
            .iter()
            .find(|(p, _)| p == f.path)
            .map(|(_, b)| *b)
            .or(f.bounds),
        ..f
    };
    let mut out: Vec<Hypothesis> = all()
        .into_iter()
        .filter(|c| !model.has(c.effect))
        .filter(|c| c.effect.spec().requires.iter().all(|r| model.has(*r)))
        .map(|c| Hypothesis {
            kind: Kind::Add,
            effect: Some(c.effect),
            fitted: c.fitted,
        })
        .collect();
    // the known model's parameters together: a few of them a few percent off each (the
    // usual case) is one recalibration, not several effects; fitted one at a time, each
    // took up part of the others' error and an effect (entrained air) could mimic the
    // rest better than any single one (measured on steps with bulk modulus -5 %, mass
    // +4 %, rated flow -3 %)
    let known: Vec<Fitted> = RECALIBRATED
        .iter()
        .map(|&path| {
            let v = param(path).expect("registered").get(model);
            bounded(Fitted {
                path,
                plausible: [
                    v * (1.0 - 0.5 * RECALIBRATION_SPAN),
                    v * (1.0 + 0.5 * RECALIBRATION_SPAN),
                ],
                log: false,
                either_sign: false,
                bounds: Some([
                    v * (1.0 - RECALIBRATION_SPAN),
                    v * (1.0 + RECALIBRATION_SPAN),
                ]),
            })
        })
        .collect();
    out.push(Hypothesis {
        kind: Kind::Recalibrate,
        effect: None,
        fitted: known,
    });
    for c in all().into_iter().filter(|c| model.has(c.effect)) {
        // the actuator's leakage is the internal leakage of section 4.4 (1e-4 L/min/bar);
        // a bench can leak a few hundred times more across worn seals
        let extra = (c.effect == Effect::InternalLeakage)
            .then(|| log("actuator.internal_leakage", [1.7e-15, 5e-12]));
        out.push(Hypothesis {
            kind: Kind::Recalibrate,
            effect: Some(c.effect),
            fitted: extra.into_iter().chain(c.fitted).map(bounded).collect(),
        });
    }
    out
}
