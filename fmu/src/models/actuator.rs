//! `actuator.fmu`: the double-rod actuator; flows in, chamber pressures and motion out.

use hbmodel::actuator::Actuator;
use hbmodel::component::actuator::ActuatorComponent;
use hbmodel::component::cosim::{ActuatorUnit, CosimUnit, PASSAGES};
use hbmodel::effects::Effect;
use hbmodel::Params;
use modeldesc::DefaultExperiment;

use super::component::{input, output, ComponentFmu, Declaration};
use super::FORCE_INPUT;
use super::{effect_switches, params_with, registry_parameters};
use crate::slave::{ModelInfo, VarDef};

/// The declaration of `actuator.fmu` over [`ActuatorUnit`].
pub struct ActuatorDecl;

pub type ActuatorFmu = ComponentFmu<ActuatorDecl>;

/// Chamber port outputs (appended last; docs/cosim.md): name, description, unit.
pub const CHAMBER_OUTPUTS: [(&str, &str, &str); 6] = [
    (
        "Q1_displaced",
        "Flow leaving chamber 1 at constant pressure (piston displacement and leakage)",
        "m3/s",
    ),
    (
        "Q2_displaced",
        "Flow leaving chamber 2 at constant pressure (piston displacement and leakage)",
        "m3/s",
    ),
    ("V1", "Oil volume of chamber 1", "m3"),
    ("V2", "Oil volume of chamber 2", "m3"),
    (
        "beta1",
        "Effective bulk modulus in chamber 1: dP1/dt = beta1/V1 (Q1 - Q1_displaced)",
        "Pa",
    ),
    (
        "beta2",
        "Effective bulk modulus in chamber 2: dP2/dt = beta2/V2 (Q2 - Q2_displaced)",
        "Pa",
    ),
];

/// Chamber port inputs, the manifold's outputs of the same names (appended last): the
/// passage delivering Q_i as a driving pressure behind an inertance, and the node behind
/// it. Left at 0 (L_i = 0), Q_i is held over a step.
pub const PASSAGE_INPUTS: [(&str, &str, &str); 10] = [
    ("P1_drive", "Pressure driving Q1 through L1, dQ1/dt = (P1_drive - P1) / L1", "Pa"),
    ("P2_drive", "Pressure driving Q2 through L2, dQ2/dt = (P2_drive - P2) / L2", "Pa"),
    ("L1", "Inertance of the passages that deliver Q1; 0 holds Q1 over a step", "kg/m4"),
    ("L2", "Inertance of the passages that deliver Q2; 0 holds Q2 over a step", "kg/m4"),
    ("V1_drive", "Oil volume of the node behind L1, dP1_drive/dt = beta1_drive/V1_drive (Q1_feed - Q1); 0 holds P1_drive", "m3"),
    ("V2_drive", "Oil volume of the node behind L2, dP2_drive/dt = beta2_drive/V2_drive (Q2_feed - Q2); 0 holds P2_drive", "m3"),
    ("beta1_drive", "Effective bulk modulus in the node behind L1", "Pa"),
    ("beta2_drive", "Effective bulk modulus in the node behind L2", "Pa"),
    ("Q1_feed", "Flow into the node behind L1 from the rest of the manifold", "m3/s"),
    ("Q2_feed", "Flow into the node behind L2 from the rest of the manifold", "m3/s"),
];

/// The inputs of a port's coupling table (CHAMBER_OUTPUTS on the manifold,
/// PASSAGE_INPUTS here), the model's inputs from `first` on, start 0: pressures (named
/// P...) and flows take any sign, inertances, volumes and moduli none below 0.
pub(super) fn port_inputs<D: Declaration>(
    table: &[(&str, &str, &str)],
    first: usize,
) -> Vec<VarDef<ComponentFmu<D>>> {
    table
        .iter()
        .enumerate()
        .map(|(k, &(name, d, unit))| {
            let signed = unit == "m3/s" || name.starts_with('P');
            let bounds = (if signed { None } else { Some(0.0) }, None);
            input(first + k, name, d, unit, 0.0, bounds)
        })
        .collect()
}

/// The effects that concern the actuator alone.
const EFFECTS: [Effect; 6] = [
    Effect::EntrainedAir,
    Effect::InternalLeakage,
    Effect::DryFriction,
    Effect::ViscousFriction,
    Effect::Payload,
    Effect::Temperature,
];

/// Built-in parameters: the chapter-4 actuator (leakage, friction) without payload.
pub fn default_params() -> Params {
    params_with(&[
        Effect::InternalLeakage,
        Effect::DryFriction,
        Effect::ViscousFriction,
    ])
}

impl Declaration for ActuatorDecl {
    fn default_params() -> Params {
        default_params()
    }

    fn info() -> ModelInfo {
        ModelInfo {
            model_name: "HydroBench.Actuator",
            model_identifier: "actuator",
            description: "Double-rod actuator with hydrostatic bearings: chamber flows and external force in, pressures and motion out",
            default_experiment: DefaultExperiment { start_time: 0.0, stop_time: 0.1, tolerance: Some(1e-6), step_size: Some(1e-4) },
            equations: &[
                "(4.1)-(4.2) chamber flow balances with leakage",
                "(4.4) piston motion with gravity, friction (4.5)-(4.13) and end stops",
                "(A.7)-(A.12) effective bulk modulus",
            ],
            parameters: Some(default_params()),
        }
    }

    fn variables() -> Vec<VarDef<ActuatorFmu>> {
        let d = default_params();
        let mut v = vec![
            input(0, "Q1", "Flow into chamber 1", "m3/s", 0.0, (None, None)),
            input(1, "Q2", "Flow into chamber 2", "m3/s", 0.0, (None, None)),
            input(
                2,
                "F_ext",
                "External force on the rod, opposing positive y",
                "N",
                0.0,
                FORCE_INPUT,
            ),
            output(0, "P1", "Pressure in chamber 1 (absolute)", "Pa").depends_on(&[]),
            output(1, "P2", "Pressure in chamber 2 (absolute)", "Pa").depends_on(&[]),
            output(2, "y", "Piston position from mid stroke", "m").depends_on(&[]),
            output(3, "v", "Piston velocity", "m/s").depends_on(&[]),
            output(4, "a", "Piston acceleration", "m/s2").depends_on(&["F_ext"]),
        ];
        v.extend(effect_switches(&EFFECTS, &d));
        v.extend(registry_parameters(
            |p| {
                p.starts_with("actuator.")
                    || p.starts_with("friction.")
                    || p.starts_with("fluid.")
                    || matches!(p, "initial_position" | "supply_pressure" | "tank_pressure")
            },
            str::to_string,
        ));
        // Appended last so that the value references above keep their numbers: the
        // chamber port's coupling terms (docs/cosim.md). Each side of the passage/chamber
        // loop carries the other's element over a step: the manifold the chamber
        // (displaced flow, volume, bulk modulus: these outputs), the actuator the passage
        // (driving pressure, inertance and the node behind: the inputs).
        v.extend(
            CHAMBER_OUTPUTS
                .iter()
                .enumerate()
                .map(|(k, &(name, d, unit))| output(5 + k, name, d, unit).depends_on(&[])),
        );
        v.extend(port_inputs(&PASSAGE_INPUTS, PASSAGES));
        v.extend(super::fixed_step_parameter());
        v
    }

    /// The bare actuator (no manifold volume or fluid mass merged into it), at rest at
    /// y0 with the chambers at half supply pressure, split to carry its weight.
    fn build(p: &Params) -> Box<dyn CosimUnit> {
        Box::new(ActuatorUnit {
            component: ActuatorComponent::new(
                Actuator::from_params(p, [0.0; 2], 0.0),
                p.fluid_in_use(),
                p.has(Effect::EntrainedAir),
                p.tank_pressure,
            ),
            y0: p.initial_position,
            supply: p.supply_pressure,
            tank: p.tank_pressure,
        })
    }

    fn start_inputs(_p: &Params) -> Vec<f64> {
        vec![0.0; PASSAGES + PASSAGE_INPUTS.len()]
    }

    fn n_outputs() -> usize {
        5 + CHAMBER_OUTPUTS.len()
    }
}
