//! `servovalve.fmu`: one MOOG D765 between supply, tank and two port pressures.

use std::path::Path;

use hbmodel::effects::Effect;
use hbmodel::servovalve::{self, PortPressures, Servovalve};
use hbmodel::solver::{integrate, SolverStats, Tolerances};
use hbmodel::Params;
use modeldesc::DefaultExperiment;
use serde::{Deserialize, Serialize};

use super::{
    effect_switches, load_params, params_with, registry_parameters, valve_model_code,
    valve_model_from, HasParams, VALVE_MODELS,
};
use super::{COMMAND_INPUT, PRESSURE_INPUT};
use crate::slave::{enum_parameter, real_input, real_output, Model, ModelInfo, RealGetter, VarDef};

#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
pub struct ValveInputs {
    pub u: f64,
    pub ports: [f64; 4],
}

pub struct ServovalveFmu {
    params: Params,
    valve: Option<Box<dyn Servovalve>>,
    x: Vec<f64>,
    inputs: ValveInputs,
    t: f64,
    /// Q_A, Q_B, x_s, dQ_A/dP_A, dQ_B/dP_B
    out: [f64; 5],
}

#[derive(Clone, Serialize, Deserialize)]
pub struct Snapshot {
    params: Params,
    x: Vec<f64>,
    inputs: ValveInputs,
    t: f64,
}

/// Built-in parameters: the thesis valve with its second-order spool and null leakage.
pub fn default_params() -> Params {
    params_with(&[Effect::ValveDynamics, Effect::InternalLeakage])
}

impl HasParams for ServovalveFmu {
    fn params(&self) -> &Params {
        &self.params
    }
    fn params_mut(&mut self) -> &mut Params {
        self.valve = None;
        &mut self.params
    }
}

impl ServovalveFmu {
    fn ports(&self) -> PortPressures {
        let [supply, tank, a, b] = self.inputs.ports;
        PortPressures { supply, tank, a, b }
    }

    fn valve(&mut self) -> Result<&dyn Servovalve, String> {
        if self.valve.is_none() {
            self.params.validate().map_err(|e| e.to_string())?;
            let v = servovalve::build(&self.params.sv1, &self.params);
            if self.x.len() != v.n_states() {
                self.x = vec![0.0; v.n_states()];
                v.initial_state(self.inputs.u, &mut self.x);
            }
            self.valve = Some(v);
        }
        self.valve.as_deref().ok_or_else(|| "no valve".to_string())
    }
}

impl Model for ServovalveFmu {
    type Snapshot = Snapshot;

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

    fn variables() -> Vec<VarDef<Self>> {
        let d = default_params();
        let mut v = vec![
            real_input(
                "u",
                "Valve command",
                "V",
                0.0,
                COMMAND_INPUT,
                |m: &Self| m.inputs.u,
                |m, x| m.inputs.u = x,
            ),
            real_input(
                "P_P",
                "Supply pressure (absolute)",
                "Pa",
                d.supply_pressure,
                PRESSURE_INPUT,
                |m: &Self| m.inputs.ports[0],
                |m, x| m.inputs.ports[0] = x,
            ),
            real_input(
                "P_T",
                "Tank pressure (absolute)",
                "Pa",
                d.tank_pressure,
                PRESSURE_INPUT,
                |m: &Self| m.inputs.ports[1],
                |m, x| m.inputs.ports[1] = x,
            ),
            real_input(
                "P_A",
                "Pressure at port A (absolute)",
                "Pa",
                0.5 * (d.supply_pressure + d.tank_pressure),
                PRESSURE_INPUT,
                |m: &Self| m.inputs.ports[2],
                |m, x| m.inputs.ports[2] = x,
            ),
            real_input(
                "P_B",
                "Pressure at port B (absolute)",
                "Pa",
                0.5 * (d.supply_pressure + d.tank_pressure),
                PRESSURE_INPUT,
                |m: &Self| m.inputs.ports[3],
                |m, x| m.inputs.ports[3] = x,
            ),
            real_output("Q_A", "Flow out of port A", "m3/s", |m: &Self| m.out[0]),
            real_output("Q_B", "Flow out of port B", "m3/s", |m: &Self| m.out[1]),
            real_output(
                "x_s",
                "Spool position (positive opens P->A and B->T)",
                "m",
                |m: &Self| m.out[2],
            )
            .depends_on(&["u"]),
        ];
        v.push(enum_parameter(
            "model",
            "Servovalve model",
            &VALVE_MODELS,
            1,
            |m: &Self| valve_model_code(m.params.sv1.model),
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
        fn out<const K: usize>(m: &ServovalveFmu) -> f64 {
            m.out[K]
        }
        let sensitivities: [(&str, &str, RealGetter<Self>); 2] = [
            (
                "dQ_A_dP_A",
                "Sensitivity of Q_A to P_A (interface Jacobian, never positive)",
                out::<3>,
            ),
            (
                "dQ_B_dP_B",
                "Sensitivity of Q_B to P_B (interface Jacobian, never positive)",
                out::<4>,
            ),
        ];
        for (name, description, get) in sensitivities {
            v.push(
                real_output(name, description, "m3/(s.Pa)", get)
                    .depends_on(&["u", "P_P", "P_T", "P_A", "P_B"]),
            );
        }
        v.push(super::fixed_step_parameter());
        v
    }

    fn instantiate(resources: Option<&Path>) -> Result<Self, String> {
        let params = load_params(resources, default_params())?;
        let mid = 0.5 * (params.supply_pressure + params.tank_pressure);
        Ok(ServovalveFmu {
            inputs: ValveInputs {
                u: 0.0,
                ports: [params.supply_pressure, params.tank_pressure, mid, mid],
            },
            params,
            valve: None,
            x: vec![],
            t: 0.0,
            out: [0.0; 5],
        })
    }

    fn initialize(&mut self, start_time: f64) -> Result<(), String> {
        self.t = start_time;
        self.valve = None;
        self.x.clear();
        self.refresh()
    }

    fn refresh(&mut self) -> Result<(), String> {
        let ports = self.ports();
        let u = self.inputs.u;
        self.valve()?;
        let v = self.valve.as_deref().ok_or("no valve")?;
        let q = v.flows(u, &self.x, &ports);
        // central differences over 1 mbar: well inside the laminar core of the land
        // law's square root, far above rounding at 200 bar
        let dp = 100.0;
        let at = |da: f64, db: f64| {
            let mut p = ports;
            p.a += da;
            p.b += db;
            v.flows(u, &self.x, &p)
        };
        let dqa = (at(dp, 0.0).a - at(-dp, 0.0).a) / (2.0 * dp);
        let dqb = (at(0.0, dp).b - at(0.0, -dp).b) / (2.0 * dp);
        self.out = [q.a, q.b, v.spool_position(u, &self.x), dqa, dqb];
        Ok(())
    }

    fn do_step(&mut self, h: f64) -> Result<(), String> {
        let u = self.inputs.u;
        self.valve()?;
        let v = self.valve.as_deref().ok_or("no valve")?;
        let n = v.n_states();
        if n > 0 {
            let mut atol = vec![0.0; n];
            v.absolute_tolerances(&mut atol);
            let scale: Vec<f64> = atol.iter().map(|a| a * 1e4).collect();
            let tol = Tolerances {
                rtol: self.params.solver.rtol,
                atol,
                fixed_step: self.params.solver.fixed_step,
            };
            let mut x = self.x.clone();
            let ports = self.ports();
            integrate(
                |_t, x, dx| v.derivatives_at(u, x, &ports, dx),
                &mut x,
                self.t,
                self.t + h,
                &tol,
                &scale,
                &mut SolverStats::default(),
            )
            .map_err(|e| e.to_string())?;
            self.x = x;
        }
        self.t += h;
        Ok(())
    }

    fn time(&self) -> f64 {
        self.t
    }

    fn snapshot(&self) -> Snapshot {
        Snapshot {
            params: self.params.clone(),
            x: self.x.clone(),
            inputs: self.inputs,
            t: self.t,
        }
    }

    fn restore(&mut self, s: Snapshot) -> Result<(), String> {
        self.params = s.params;
        self.valve = None;
        self.x = s.x;
        self.inputs = s.inputs;
        self.t = s.t;
        self.valve()?;
        if self.x.len() != self.valve.as_ref().map_or(0, |v| v.n_states()) {
            return Err("state size does not match the valve model".into());
        }
        self.refresh()
    }

    fn relative_tolerance(&mut self) -> Option<&mut f64> {
        Some(&mut self.params_mut().solver.rtol)
    }
}
