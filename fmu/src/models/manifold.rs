//! `manifold.fmu`: the manifold between the valve ports and the chambers.
//!
//! Valve port flows and chamber pressures in; port pressures and chamber flows out
//! (DESIGN.md port causality). With `manifold_volume` and `manifold_inertia` on (the
//! default) it is the C-R-I-C network of chapter 3, whose chamber-side half volumes of the
//! N-V passages belong with the actuator's chambers; with them off it joins each valve
//! port straight to its chamber (or to tank), as in (II.1).

use std::path::Path;

use hbmodel::actuator::{fluid_in_use, oil_stiffness};
use hbmodel::effects::Effect;
use hbmodel::manifold::{Circuit, NetworkState};
use hbmodel::solver::{integrate, SolverStats, Tolerances};
use hbmodel::Params;
use modeldesc::DefaultExperiment;
use serde::{Deserialize, Serialize};

use super::PRESSURE_INPUT;
use super::{effect_switches, load_params, params_with, registry_parameters, HasParams};
use crate::slave::{
    integer_parameter, real_input, real_output, Model, ModelInfo, RealGetter, RealSetter, VarDef,
};

const EFFECTS: [Effect; 5] = [
    Effect::ManifoldVolume,
    Effect::ManifoldInertia,
    Effect::ManifoldLosses,
    Effect::EntrainedAir,
    Effect::Temperature,
];

#[derive(Clone, Serialize, Deserialize)]
pub struct Snapshot {
    params: Params,
    /// node pressures then passage flows (empty before initialization)
    x: Vec<f64>,
    /// Q_A1, Q_B1, Q_A2, Q_B2, P1, P2
    inputs: [f64; 6],
    t: f64,
    /// dQ_A1/dP_A1, dQ_B1/dP_B1, dQ_A2/dP_A2, dQ_B2/dP_B2 (zero in snapshots of before)
    #[serde(default)]
    sensitivities: [f64; 4],
}

pub struct ManifoldFmu {
    s: Snapshot,
    circuit: Option<Circuit>,
    /// P_A1, P_B1, P_A2, P_B2, Q1, Q2
    out: [f64; 6],
}

/// Built-in parameters: the chapter-3 network (volumes, inertia, losses) in mode 3.
pub fn default_params() -> Params {
    params_with(&[
        Effect::ManifoldVolume,
        Effect::ManifoldInertia,
        Effect::ManifoldLosses,
    ])
}

impl HasParams for ManifoldFmu {
    fn params(&self) -> &Params {
        &self.s.params
    }
    fn params_mut(&mut self) -> &mut Params {
        self.circuit = None;
        &mut self.s.params
    }
}

impl ManifoldFmu {
    fn circuit(&mut self) -> Result<&Circuit, String> {
        if self.circuit.is_none() {
            self.s.params.validate().map_err(|e| e.to_string())?;
            let c = Circuit::from_params(&self.s.params);
            let n = c.nodes.len() + c.passages.len();
            if self.s.x.len() != n {
                // nodes start between the two chamber pressures, passages at rest
                let mid = 0.5 * (self.s.inputs[4] + self.s.inputs[5]);
                self.s.x = (0..n)
                    .map(|k| if k < c.nodes.len() { mid } else { 0.0 })
                    .collect();
            }
            self.circuit = Some(c);
        }
        self.circuit
            .as_ref()
            .ok_or_else(|| "no circuit".to_string())
    }

    /// Network right-hand side; returns the chamber flows. Over a communication step
    /// each valve port flow follows its node's pressure to first order,
    /// Q + dQ/dP (p - p0), `linear` holding the sensitivities and the port pressures p0
    /// at the step's start (all zero: the flows are held).
    fn derivatives(
        c: &Circuit,
        p: &Params,
        inputs: &[f64; 6],
        linear: (&[f64; 4], &[f64; 4]),
        x: &[f64],
        dx: &mut [f64],
    ) -> [f64; 2] {
        let fluid = fluid_in_use(p);
        let air = p.has(Effect::EntrainedAir);
        let nn = c.nodes.len();
        let state = NetworkState {
            nodes: &x[..nn],
            flows: &x[nn..],
            chambers: [inputs[4], inputs[5]],
            tank: p.tank_pressure,
        };
        let (g, p0) = linear;
        let q = |k: usize| inputs[k] + g[k] * (state.pressure(c.valve_ports[k / 2][k % 2]) - p0[k]);
        let ports = [[q(0), q(1)], [q(2), q(3)]];
        let (dn, df) = dx.split_at_mut(nn);
        c.derivatives(&state, &ports, |q| oil_stiffness(&fluid, air, q), dn, df)
    }
}

impl Model for ManifoldFmu {
    type Snapshot = Snapshot;

    fn info() -> ModelInfo {
        ModelInfo {
            model_name: "HydroBench.Manifold",
            model_identifier: "manifold",
            description: "Three-mode manifold between the two servovalves and the actuator (C-R-I-C passages, chapter 3)",
            default_experiment: DefaultExperiment { start_time: 0.0, stop_time: 0.05, tolerance: Some(1e-6), step_size: Some(1e-4) },
            enumerations: vec![],
            equations: &[
                "(3.2) passage end volumes, (3.3) passage inertia",
                "(3.5)-(3.7) abacus-based pressure drop, (3.4) solenoid valves, flow reducers",
            ],
            parameters: Some(default_params()),
        }
    }

    fn variables() -> Vec<VarDef<Self>> {
        let d = default_params();
        let mid = 0.5 * (d.supply_pressure + d.tank_pressure);
        let mut v = vec![
            real_input("Q_A1", "Flow out of port A of SV1", "m3/s", 0.0, (None, None), |m: &Self| m.s.inputs[0], |m, x| m.s.inputs[0] = x),
            real_input("Q_B1", "Flow out of port B of SV1", "m3/s", 0.0, (None, None), |m: &Self| m.s.inputs[1], |m, x| m.s.inputs[1] = x),
            real_input("Q_A2", "Flow out of port A of SV2", "m3/s", 0.0, (None, None), |m: &Self| m.s.inputs[2], |m, x| m.s.inputs[2] = x),
            real_input("Q_B2", "Flow out of port B of SV2", "m3/s", 0.0, (None, None), |m: &Self| m.s.inputs[3], |m, x| m.s.inputs[3] = x),
            real_input("P1", "Pressure in chamber 1", "Pa", mid, PRESSURE_INPUT, |m: &Self| m.s.inputs[4], |m, x| m.s.inputs[4] = x),
            real_input("P2", "Pressure in chamber 2", "Pa", mid, PRESSURE_INPUT, |m: &Self| m.s.inputs[5], |m, x| m.s.inputs[5] = x),
            real_output("P_A1", "Pressure at port A of SV1", "Pa", |m: &Self| m.out[0]).depends_on(&["P1", "P2"]),
            real_output("P_B1", "Pressure at port B of SV1", "Pa", |m: &Self| m.out[1]).depends_on(&["P1", "P2"]),
            real_output("P_A2", "Pressure at port A of SV2", "Pa", |m: &Self| m.out[2]).depends_on(&["P1", "P2"]),
            real_output("P_B2", "Pressure at port B of SV2", "Pa", |m: &Self| m.out[3]).depends_on(&["P1", "P2"]),
            real_output("Q1", "Flow delivered into chamber 1", "m3/s", |m: &Self| m.out[4]).depends_on(&["Q_A1", "Q_B1", "Q_A2", "Q_B2"]),
            real_output("Q2", "Flow delivered into chamber 2", "m3/s", |m: &Self| m.out[5]).depends_on(&["Q_A1", "Q_B1", "Q_A2", "Q_B2"]),
            integer_parameter("mode", "Working mode: 1 = SV1 4-way, 2 = both 4-way in parallel, 3 = each 3-way on one chamber", d.mode.number() as i32, 1, 3, |m: &Self| m.s.params.mode.number() as i32, |m, k| {
                if let Ok(mode) = hbmodel::Mode::try_from(k as u8) {
                    m.params_mut().mode = mode;
                }
            }),
        ];
        v.extend(effect_switches(&EFFECTS, &d));
        v.extend(registry_parameters(
            |p| p.starts_with("manifold.") || p.starts_with("fluid.") || p == "tank_pressure",
            str::to_string,
        ));
        // Appended last so that the value references above keep their numbers: the valves'
        // dQ_*_dP_* outputs, with which the port flows follow the port-node pressures
        // within a step (interface-Jacobian coupling, docs/cosim.md). 0 holds them.
        fn get<const K: usize>(m: &ManifoldFmu) -> f64 {
            m.s.sensitivities[K]
        }
        fn set<const K: usize>(m: &mut ManifoldFmu, x: f64) {
            m.s.sensitivities[K] = x;
        }
        let inputs: [(&str, &str, RealGetter<Self>, RealSetter<Self>); 4] = [
            ("dQ_A1_dP_A1", "SV1's dQ_A_dP_A", get::<0>, set::<0>),
            ("dQ_B1_dP_B1", "SV1's dQ_B_dP_B", get::<1>, set::<1>),
            ("dQ_A2_dP_A2", "SV2's dQ_A_dP_A", get::<2>, set::<2>),
            ("dQ_B2_dP_B2", "SV2's dQ_B_dP_B", get::<3>, set::<3>),
        ];
        v.extend(inputs.into_iter().map(|(name, from, get, set)| {
            let d = format!("Sensitivity of the port flow to the port pressure (from {from}); 0 holds the flow over a step");
            real_input(name, &d, "m3/(s.Pa)", 0.0, (None, Some(0.0)), get, set)
        }));
        v
    }

    fn instantiate(resources: Option<&Path>) -> Result<Self, String> {
        let params = load_params(resources, default_params())?;
        let mid = 0.5 * (params.supply_pressure + params.tank_pressure);
        Ok(ManifoldFmu {
            s: Snapshot {
                params,
                x: vec![],
                inputs: [0.0, 0.0, 0.0, 0.0, mid, mid],
                t: 0.0,
                sensitivities: [0.0; 4],
            },
            circuit: None,
            out: [0.0; 6],
        })
    }

    fn initialize(&mut self, start_time: f64) -> Result<(), String> {
        self.s.t = start_time;
        self.s.x.clear();
        self.circuit = None;
        self.refresh()
    }

    fn refresh(&mut self) -> Result<(), String> {
        self.circuit()?;
        let c = self.circuit.as_ref().ok_or("no circuit")?;
        let mut dx = vec![0.0; self.s.x.len()];
        let none = [0.0; 4];
        let q = Self::derivatives(
            c,
            &self.s.params,
            &self.s.inputs,
            (&none, &none),
            &self.s.x,
            &mut dx,
        );
        let nn = c.nodes.len();
        let state = NetworkState {
            nodes: &self.s.x[..nn],
            flows: &self.s.x[nn..],
            chambers: [self.s.inputs[4], self.s.inputs[5]],
            tank: self.s.params.tank_pressure,
        };
        let pr = |v: usize, k: usize| state.pressure(c.valve_ports[v][k]);
        self.out = [pr(0, 0), pr(0, 1), pr(1, 0), pr(1, 1), q[0], q[1]];
        Ok(())
    }

    fn do_step(&mut self, h: f64) -> Result<(), String> {
        self.circuit()?;
        let c = self.circuit.as_ref().ok_or("no circuit")?;
        let n = self.s.x.len();
        if n > 0 {
            let nn = c.nodes.len();
            let f = (self.s.params.solver.rtol / 1e-6).min(1.0);
            let atol: Vec<f64> = (0..n).map(|k| if k < nn { f } else { 1e-8 * f }).collect();
            let scale: Vec<f64> = (0..n).map(|k| if k < nn { 1e6 } else { 1e-5 }).collect();
            let tol = Tolerances {
                rtol: self.s.params.solver.rtol,
                atol,
            };
            let (p, inputs) = (&self.s.params, self.s.inputs);
            let mut x = self.s.x.clone();
            let state = NetworkState {
                nodes: &x[..nn],
                flows: &x[nn..],
                chambers: [inputs[4], inputs[5]],
                tank: p.tank_pressure,
            };
            let p0: [f64; 4] = std::array::from_fn(|k| state.pressure(c.valve_ports[k / 2][k % 2]));
            let g = self.s.sensitivities;
            integrate(
                |_t, x, dx| {
                    Self::derivatives(c, p, &inputs, (&g, &p0), x, dx);
                },
                &mut x,
                self.s.t,
                self.s.t + h,
                &tol,
                &scale,
                &mut SolverStats::default(),
            )
            .map_err(|e| e.to_string())?;
            self.s.x = x;
        }
        self.s.t += h;
        Ok(())
    }

    fn time(&self) -> f64 {
        self.s.t
    }

    fn snapshot(&self) -> Snapshot {
        self.s.clone()
    }

    fn restore(&mut self, s: Snapshot) -> Result<(), String> {
        self.s = s;
        self.circuit = None;
        self.refresh()
    }
}
