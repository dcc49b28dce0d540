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
use hbmodel::manifold::{Circuit, NetworkState, Port};
use hbmodel::solver::{integrate, SolverStats, Tolerances};
use hbmodel::Params;
use modeldesc::DefaultExperiment;
use serde::{Deserialize, Serialize};

use super::actuator::{port_inputs, CHAMBER_OUTPUTS, PASSAGE_INPUTS};
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
    /// Q1_displaced, Q2_displaced, V1, V2, beta1, beta2 of the actuator (zero in
    /// snapshots of before: the chamber pressures are held over a step)
    #[serde(default)]
    chambers: [f64; 6],
}

pub struct ManifoldFmu {
    s: Snapshot,
    circuit: Option<Circuit>,
    /// P_A1, P_B1, P_A2, P_B2, Q1, Q2, P1_drive, P2_drive, L1, L2, V1_drive, V2_drive,
    /// beta1_drive, beta2_drive, Q1_feed, Q2_feed
    out: [f64; 16],
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

    /// Network right-hand side for the chamber pressures `chambers`; returns the chamber
    /// flows. Over a communication step each valve port flow follows its node's pressure
    /// to first order, Q + dQ/dP (p - p0), `linear` holding the sensitivities and the
    /// port pressures p0 at the step's start (all zero: the flows are held).
    fn derivatives(
        c: &Circuit,
        p: &Params,
        inputs: &[f64; 6],
        chambers: [f64; 2],
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
            chambers,
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
        // Appended after those, for the chamber port (docs/cosim.md): each side of the
        // passage/chamber loop carries the other's element over a step. The actuator's
        // chamber terms let this manifold carry the chamber pressures,
        // P_i' = beta_i/V_i (Q_i - Qi_displaced) (V_i 0, the default, holds P_i); the
        // passage terms let the actuator carry the chamber flows. Names and descriptions
        // are the actuator's, so that the two ends of each connection agree.
        fn chamber<const K: usize>(m: &ManifoldFmu) -> f64 {
            m.s.chambers[K]
        }
        fn set_chamber<const K: usize>(m: &mut ManifoldFmu, x: f64) {
            m.s.chambers[K] = x;
        }
        let access: [(RealGetter<Self>, RealSetter<Self>); 6] = [
            (chamber::<0>, set_chamber::<0>),
            (chamber::<1>, set_chamber::<1>),
            (chamber::<2>, set_chamber::<2>),
            (chamber::<3>, set_chamber::<3>),
            (chamber::<4>, set_chamber::<4>),
            (chamber::<5>, set_chamber::<5>),
        ];
        v.extend(port_inputs(&CHAMBER_OUTPUTS, access));
        fn out<const K: usize>(m: &ManifoldFmu) -> f64 {
            m.out[K]
        }
        let getters: [RealGetter<Self>; 10] = [
            out::<6>, out::<7>, out::<8>, out::<9>, out::<10>, out::<11>, out::<12>, out::<13>,
            out::<14>, out::<15>,
        ];
        v.extend(
            PASSAGE_INPUTS
                .iter()
                .zip(getters)
                .map(|(&(name, d, unit), get)| {
                    real_output(name, d, unit, get).depends_on(&["P1", "P2"])
                }),
        );
        v.push(super::fixed_step_parameter());
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
                chambers: [0.0; 6],
            },
            circuit: None,
            out: [0.0; 16],
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
        let chambers = [self.s.inputs[4], self.s.inputs[5]];
        let q = Self::derivatives(
            c,
            &self.s.params,
            &self.s.inputs,
            chambers,
            (&none, &none),
            &self.s.x,
            &mut dx,
        );
        let nn = c.nodes.len();
        let state = NetworkState {
            nodes: &self.s.x[..nn],
            flows: &self.s.x[nn..],
            chambers,
            tank: self.s.params.tank_pressure,
        };
        let pr = |v: usize, k: usize| state.pressure(c.valve_ports[v][k]);
        // The passages at each chamber as one driving pressure behind one inertance: a
        // passage flow counts into a chamber it ends at and out of one it starts from,
        // and either way its rate falls by 1/inertance per pascal of chamber pressure;
        // in parallel, L = 1 / sum(1/L_k) and P_drive = P + L dQ/dt. With a single
        // passage (every mode of the network: N-V), the node behind it goes along: its
        // pressure follows the passage flow within a step, p' = beta/V (Q_feed - Q),
        // stiffer than the chamber by its smaller volume, so it cannot be held.
        let (mut rate, mut admittance, mut count) = ([0.0; 2], [0.0; 2], [0; 2]);
        let mut node = [None; 2];
        for (pass, d) in c.passages.iter().zip(&dx[nn..]) {
            for (end, other, sign) in [(pass.to, pass.from, 1.0), (pass.from, pass.to, -1.0)] {
                if let Port::Chamber(ch) = end {
                    rate[ch] += sign * d;
                    admittance[ch] += 1.0 / pass.inertance;
                    count[ch] += 1;
                    if let Port::Node(k) = other {
                        node[ch] = Some(k);
                    }
                }
            }
        }
        let l = admittance.map(|a| if a > 0.0 { 1.0 / a } else { 0.0 });
        let drive: [f64; 2] = std::array::from_fn(|ch| chambers[ch] + l[ch] * rate[ch]);
        let fluid = fluid_in_use(&self.s.params);
        let air = self.s.params.has(Effect::EntrainedAir);
        // (volume, bulk modulus, flow fed into the node by all but the chamber's passage)
        let behind: [(f64, f64, f64); 2] = std::array::from_fn(|ch| match node[ch] {
            Some(k) if count[ch] == 1 => {
                let (v, b) = (c.nodes[k].volume, oil_stiffness(&fluid, air, self.s.x[k]));
                // dp/dt = b/V (Q_feed - Q_ch)
                (v, b, dx[k] * v / b + q[ch])
            }
            _ => (0.0, 0.0, 0.0),
        });
        self.out = [
            pr(0, 0),
            pr(0, 1),
            pr(1, 0),
            pr(1, 1),
            q[0],
            q[1],
            drive[0],
            drive[1],
            l[0],
            l[1],
            behind[0].0,
            behind[1].0,
            behind[0].1,
            behind[1].1,
            behind[0].2,
            behind[1].2,
        ];
        Ok(())
    }

    fn do_step(&mut self, h: f64) -> Result<(), String> {
        self.circuit()?;
        let c = self.circuit.as_ref().ok_or("no circuit")?;
        let n = self.s.x.len();
        if n > 0 {
            let nn = c.nodes.len();
            let f = (self.s.params.solver.rtol / 1e-6).min(1.0);
            let mut atol: Vec<f64> = (0..n).map(|k| if k < nn { f } else { 1e-8 * f }).collect();
            let mut scale: Vec<f64> = (0..n).map(|k| if k < nn { 1e6 } else { 1e-5 }).collect();
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
            // With the actuator's chamber terms connected, the chamber pressures become
            // states of this step, P_i' = K_i (Q_i - Qi_displaced): the passage flows then
            // meet the pressure their own inflow builds instead of a held one, which closes
            // the passage/chamber loop (near 780 Hz) within the step (docs/cosim.md).
            let [qd1, qd2, v1, v2, b1, b2] = self.s.chambers;
            let stiffness = |b: f64, v: f64| if v > 0.0 { b / v } else { 0.0 };
            let (k1, k2) = (stiffness(b1, v1), stiffness(b2, v2));
            let carried = v1 > 0.0 || v2 > 0.0;
            if carried {
                x.extend([inputs[4], inputs[5]]);
                atol.extend([f; 2]);
                scale.extend([1e6; 2]);
            }
            let tol = Tolerances {
                rtol: self.s.params.solver.rtol,
                atol,
                fixed_step: self.s.params.solver.fixed_step,
            };
            integrate(
                |_t, x, dx| {
                    if carried {
                        let ch = [x[n], x[n + 1]];
                        let q =
                            Self::derivatives(c, p, &inputs, ch, (&g, &p0), &x[..n], &mut dx[..n]);
                        dx[n] = k1 * (q[0] - qd1);
                        dx[n + 1] = k2 * (q[1] - qd2);
                    } else {
                        let ch = [inputs[4], inputs[5]];
                        Self::derivatives(c, p, &inputs, ch, (&g, &p0), x, dx);
                    }
                },
                &mut x,
                self.s.t,
                self.s.t + h,
                &tol,
                &scale,
                &mut SolverStats::default(),
            )
            .map_err(|e| e.to_string())?;
            x.truncate(n);
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
        // a state from bytes must be one the manifold can be in (issue 16, item 7):
        // the circuit's size, finite values, no negative absolute pressure
        if !s.x.is_empty() {
            s.params.validate().map_err(|e| e.to_string())?;
            let c = Circuit::from_params(&s.params);
            let nn = c.nodes.len();
            if s.x.len() != nn + c.passages.len() {
                return Err(format!(
                    "a manifold state of this circuit has {} values",
                    nn + c.passages.len()
                ));
            }
            if s.x.iter().any(|v| !v.is_finite()) || s.x[..nn].iter().any(|p| *p < 0.0) {
                return Err(
                    "the state holds a non-finite value or a negative absolute pressure".into(),
                );
            }
        }
        self.s = s;
        self.circuit = None;
        self.refresh()
    }

    fn relative_tolerance(&mut self) -> Option<&mut f64> {
        Some(&mut self.params_mut().solver.rtol)
    }
}
