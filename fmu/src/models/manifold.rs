//! `manifold.fmu`: the manifold between the valve ports and the chambers.
//!
//! Valve port flows and chamber pressures in; port pressures and chamber flows out
//! (DESIGN.md port causality). With `manifold_volume` and `manifold_inertia` on (the
//! default) it is the C-R-I-C network of chapter 3, whose chamber-side half volumes of the
//! N-V passages belong with the actuator's chambers; with them off it joins each valve
//! port straight to its chamber (or to tank), as in (II.1).

use hbmodel::component::cosim::{CosimUnit, NetworkUnit, CHAMBERS, SENSITIVITIES};
use hbmodel::component::network::Network;
use hbmodel::effects::Effect;
use hbmodel::manifold::Circuit;
use hbmodel::Params;
use modeldesc::DefaultExperiment;

use super::actuator::{port_inputs, CHAMBER_OUTPUTS, PASSAGE_INPUTS};
use super::component::{input, output, ComponentFmu, Declaration};
use super::PRESSURE_INPUT;
use super::{effect_switches, params_with, registry_parameters, HasParams};
use crate::slave::{integer_parameter, ModelInfo, VarDef};

/// The declaration of `manifold.fmu` over [`NetworkUnit`].
pub struct ManifoldDecl;

pub type ManifoldFmu = ComponentFmu<ManifoldDecl>;

const EFFECTS: [Effect; 5] = [
    Effect::ManifoldVolume,
    Effect::ManifoldInertia,
    Effect::ManifoldLosses,
    Effect::EntrainedAir,
    Effect::Temperature,
];

/// Built-in parameters: the chapter-3 network (volumes, inertia, losses) in mode 3.
pub fn default_params() -> Params {
    params_with(&[
        Effect::ManifoldVolume,
        Effect::ManifoldInertia,
        Effect::ManifoldLosses,
    ])
}

impl Declaration for ManifoldDecl {
    fn default_params() -> Params {
        default_params()
    }

    fn info() -> ModelInfo {
        ModelInfo {
            model_name: "HydroBench.Manifold",
            model_identifier: "manifold",
            description: "Three-mode manifold between the two servovalves and the actuator (C-R-I-C passages, chapter 3)",
            default_experiment: DefaultExperiment { start_time: 0.0, stop_time: 0.05, tolerance: Some(1e-6), step_size: Some(1e-4) },
            equations: &[
                "(3.2) passage end volumes, (3.3) passage inertia",
                "(3.5)-(3.7) abacus-based pressure drop, (3.4) solenoid valves, flow reducers",
            ],
            parameters: Some(default_params()),
        }
    }

    fn variables() -> Vec<VarDef<ManifoldFmu>> {
        let d = default_params();
        let mid = 0.5 * (d.supply_pressure + d.tank_pressure);
        let flow = (None, None);
        let mut v = vec![
            input(0, "Q_A1", "Flow out of port A of SV1", "m3/s", 0.0, flow),
            input(1, "Q_B1", "Flow out of port B of SV1", "m3/s", 0.0, flow),
            input(2, "Q_A2", "Flow out of port A of SV2", "m3/s", 0.0, flow),
            input(3, "Q_B2", "Flow out of port B of SV2", "m3/s", 0.0, flow),
            input(4, "P1", "Pressure in chamber 1", "Pa", mid, PRESSURE_INPUT),
            input(5, "P2", "Pressure in chamber 2", "Pa", mid, PRESSURE_INPUT),
            output(0, "P_A1", "Pressure at port A of SV1", "Pa").depends_on(&["P1", "P2"]),
            output(1, "P_B1", "Pressure at port B of SV1", "Pa").depends_on(&["P1", "P2"]),
            output(2, "P_A2", "Pressure at port A of SV2", "Pa").depends_on(&["P1", "P2"]),
            output(3, "P_B2", "Pressure at port B of SV2", "Pa").depends_on(&["P1", "P2"]),
            output(4, "Q1", "Flow delivered into chamber 1", "m3/s")
                .depends_on(&["Q_A1", "Q_B1", "Q_A2", "Q_B2"]),
            output(5, "Q2", "Flow delivered into chamber 2", "m3/s")
                .depends_on(&["Q_A1", "Q_B1", "Q_A2", "Q_B2"]),
            integer_parameter(
                "mode",
                "Working mode: 1 = SV1 4-way, 2 = both 4-way in parallel, 3 = each 3-way on one chamber",
                d.mode.number() as i32,
                1,
                3,
                |m: &ManifoldFmu| m.params().mode.number() as i32,
                |m, k| {
                    if let Ok(mode) = hbmodel::Mode::try_from(k as u8) {
                        m.params_mut().mode = mode;
                    }
                },
            ),
        ];
        v.extend(effect_switches(&EFFECTS, &d));
        v.extend(registry_parameters(
            |p| p.starts_with("manifold.") || p.starts_with("fluid.") || p == "tank_pressure",
            str::to_string,
        ));
        // Appended last so that the value references above keep their numbers: the valves'
        // dQ_*_dP_* outputs, with which the port flows follow the port-node pressures
        // within a step (interface-Jacobian coupling, docs/cosim.md). 0 holds them.
        let sensitivities = [
            ("dQ_A1_dP_A1", "SV1's dQ_A_dP_A"),
            ("dQ_B1_dP_B1", "SV1's dQ_B_dP_B"),
            ("dQ_A2_dP_A2", "SV2's dQ_A_dP_A"),
            ("dQ_B2_dP_B2", "SV2's dQ_B_dP_B"),
        ];
        v.extend(sensitivities.into_iter().enumerate().map(|(k, (name, from))| {
            let d = format!("Sensitivity of the port flow to the port pressure (from {from}); 0 holds the flow over a step");
            input(SENSITIVITIES + k, name, &d, "m3/(s.Pa)", 0.0, (None, Some(0.0)))
        }));
        // Appended after those, for the chamber port (docs/cosim.md): each side of the
        // passage/chamber loop carries the other's element over a step. The actuator's
        // chamber terms let this manifold carry the chamber pressures,
        // P_i' = beta_i/V_i (Q_i - Qi_displaced) (V_i 0, the default, holds P_i); the
        // passage terms let the actuator carry the chamber flows. Names and descriptions
        // are the actuator's, so that the two ends of each connection agree.
        v.extend(port_inputs(&CHAMBER_OUTPUTS, CHAMBERS));
        v.extend(
            PASSAGE_INPUTS
                .iter()
                .enumerate()
                .map(|(k, &(name, d, unit))| {
                    output(6 + k, name, d, unit).depends_on(&["P1", "P2"])
                }),
        );
        v.extend(super::fixed_step_parameter());
        v
    }

    /// The network of the mode and effects, with the oil in use.
    fn build(p: &Params) -> Box<dyn CosimUnit> {
        Box::new(NetworkUnit(Network::new(
            Circuit::from_params(p),
            p.fluid_in_use(),
            p.has(Effect::EntrainedAir),
            p.tank_pressure,
        )))
    }

    fn start_inputs(p: &Params) -> Vec<f64> {
        let mid = 0.5 * (p.supply_pressure + p.tank_pressure);
        let mut u = vec![0.0; CHAMBERS + CHAMBER_OUTPUTS.len()];
        u[4] = mid;
        u[5] = mid;
        u
    }

    fn n_outputs() -> usize {
        6 + PASSAGE_INPUTS.len()
    }
}
