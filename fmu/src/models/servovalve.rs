//! `servovalve.fmu`: one MOOG D765 between supply, tank and two port pressures.

use hbmodel::component::cosim::{CosimUnit, ValveUnit};
use hbmodel::component::valve::Valve;
use hbmodel::effects::Effect;
use hbmodel::servovalve;
use hbmodel::Params;
use modeldesc::DefaultExperiment;

use super::component::{input, output, ComponentFmu, Declaration};
use super::{
    effect_switches, params_with, registry_parameters, valve_model_code, valve_model_from,
    HasParams, VALVE_MODELS,
};
use super::{COMMAND_INPUT, PRESSURE_INPUT};
use crate::slave::{enum_parameter, ModelInfo, VarDef};

/// The declaration of `servovalve.fmu` over [`ValveUnit`].
pub struct ServovalveDecl;

pub type ServovalveFmu = ComponentFmu<ServovalveDecl>;

/// Built-in parameters: the thesis valve with its second-order spool and null leakage.
pub fn default_params() -> Params {
    params_with(&[Effect::ValveDynamics, Effect::InternalLeakage])
}

impl Declaration for ServovalveDecl {
    fn default_params() -> Params {
        default_params()
    }

    fn info() -> ModelInfo {
        ModelInfo {
            model_name: "HydroBench.Servovalve",
            model_identifier: "servovalve",
            description: "MOOG D765 servovalve: command and port pressures in, port flows and spool position out",
            default_experiment: DefaultExperiment { start_time: 0.0, stop_time: 0.05, tolerance: Some(1e-6), step_size: Some(1e-4) },
            equations: &[
                "(II.2) land flow Qn/un * u * sqrt(dp/(dPn/2)) on the four lands",
                "null leakage of the lands, second-order spool with a rate limit",
            ],
            parameters: Some(default_params()),
        }
    }

    fn variables() -> Vec<VarDef<ServovalveFmu>> {
        let d = default_params();
        let mid = 0.5 * (d.supply_pressure + d.tank_pressure);
        let mut v = vec![
            input(0, "u", "Valve command", "V", 0.0, COMMAND_INPUT),
            input(
                1,
                "P_P",
                "Supply pressure (absolute)",
                "Pa",
                d.supply_pressure,
                PRESSURE_INPUT,
            ),
            input(
                2,
                "P_T",
                "Tank pressure (absolute)",
                "Pa",
                d.tank_pressure,
                PRESSURE_INPUT,
            ),
            input(
                3,
                "P_A",
                "Pressure at port A (absolute)",
                "Pa",
                mid,
                PRESSURE_INPUT,
            ),
            input(
                4,
                "P_B",
                "Pressure at port B (absolute)",
                "Pa",
                mid,
                PRESSURE_INPUT,
            ),
            output(0, "Q_A", "Flow out of port A", "m3/s"),
            output(1, "Q_B", "Flow out of port B", "m3/s"),
            output(
                2,
                "x_s",
                "Spool position (positive opens P->A and B->T)",
                "m",
            )
            .depends_on(&["u"]),
        ];
        v.push(enum_parameter(
            "model",
            "Servovalve model",
            &VALVE_MODELS,
            1,
            |m: &ServovalveFmu| valve_model_code(m.params().sv1.model),
            |m, k| m.params_mut().sv1.model = valve_model_from(k),
        ));
        v.extend(effect_switches(
            &[
                Effect::ValveDynamics,
                Effect::InternalLeakage,
                Effect::Temperature,
            ],
            &d,
        ));
        v.extend(registry_parameters(
            |p| p.starts_with("sv1.") || p == "fluid.temperature",
            |n| n.trim_start_matches("sv1.").to_string(),
        ));
        // Appended last so that the value references above keep their numbers. A master
        // hands these to the manifold (dQ_*_dP_* inputs) so that the stiff valve/port-node
        // loop is closed inside the manifold's implicit solver (docs/cosim.md).
        let sensitivities = [
            (
                3,
                "dQ_A_dP_A",
                "Sensitivity of Q_A to P_A (interface Jacobian, never positive)",
            ),
            (
                4,
                "dQ_B_dP_B",
                "Sensitivity of Q_B to P_B (interface Jacobian, never positive)",
            ),
        ];
        for (k, name, description) in sensitivities {
            v.push(
                output(k, name, description, "m3/(s.Pa)")
                    .depends_on(&["u", "P_P", "P_T", "P_A", "P_B"]),
            );
        }
        v.extend(super::fixed_step_parameter());
        v
    }

    /// SV1's parameters, with the effects `valve_dynamics`, `internal_leakage` and
    /// `temperature`.
    fn build(p: &Params) -> Box<dyn CosimUnit> {
        Box::new(ValveUnit(Valve::new(
            servovalve::build(&p.sv1, p).into(),
            "",
        )))
    }

    fn start_inputs(p: &Params) -> Vec<f64> {
        let mid = 0.5 * (p.supply_pressure + p.tank_pressure);
        vec![0.0, p.supply_pressure, p.tank_pressure, mid, mid]
    }

    fn n_outputs() -> usize {
        5
    }
}
