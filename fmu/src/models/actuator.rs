//! `actuator.fmu`: the double-rod actuator; flows in, chamber pressures and motion out.

use std::path::Path;

use hbmodel::actuator::{fluid_in_use, oil_stiffness, Actuator};
use hbmodel::effects::Effect;
use hbmodel::solver::{integrate, SolverStats, Tolerances};
use hbmodel::Params;
use modeldesc::DefaultExperiment;
use serde::{Deserialize, Serialize};

use super::FORCE_INPUT;
use super::{effect_switches, load_params, params_with, registry_parameters, HasParams};
use crate::slave::{real_input, real_output, Model, ModelInfo, RealGetter, RealSetter, VarDef};

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
/// PASSAGE_INPUTS here), start 0: pressures (named P...) and flows take any sign,
/// inertances, volumes and moduli none below 0.
pub(super) fn port_inputs<M: 'static>(
    table: &[(&str, &str, &str)],
    access: impl IntoIterator<Item = (RealGetter<M>, RealSetter<M>)>,
) -> Vec<VarDef<M>> {
    table
        .iter()
        .zip(access)
        .map(|(&(name, d, unit), (get, set))| {
            let signed = unit == "m3/s" || name.starts_with('P');
            let bounds = (if signed { None } else { Some(0.0) }, None);
            real_input(name, d, unit, 0.0, bounds, get, set)
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

#[derive(Clone, Serialize, Deserialize)]
pub struct Snapshot {
    params: Params,
    /// y, v, P1, P2 (empty before initialization)
    x: Vec<f64>,
    /// Q1, Q2, F_ext
    inputs: [f64; 3],
    t: f64,
    /// PASSAGE_INPUTS: the manifold's passages at the chambers, a driving pressure
    /// behind an inertance, and the nodes behind them (zero in snapshots of before:
    /// flows held)
    #[serde(default)]
    passages: [f64; 10],
}

pub struct ActuatorFmu {
    s: Snapshot,
    act: Option<Actuator>,
    /// P1, P2, y, v, a, Q1_displaced, Q2_displaced, V1, V2, beta1, beta2
    out: [f64; 11],
}

/// Built-in parameters: the chapter-4 actuator (leakage, friction) without payload.
pub fn default_params() -> Params {
    params_with(&[
        Effect::InternalLeakage,
        Effect::DryFriction,
        Effect::ViscousFriction,
    ])
}

impl HasParams for ActuatorFmu {
    fn params(&self) -> &Params {
        &self.s.params
    }
    fn params_mut(&mut self) -> &mut Params {
        self.act = None;
        &mut self.s.params
    }
}

impl ActuatorFmu {
    /// Build the actuator; the state starts at rest at y0 with the chambers at half
    /// supply pressure, split to carry the piston's weight.
    fn actuator(&mut self) -> Result<&Actuator, String> {
        if self.act.is_none() {
            let p = &self.s.params;
            p.validate().map_err(|e| e.to_string())?;
            let act = Actuator::from_params(p, [0.0; 2], 0.0);
            if self.s.x.len() != 4 {
                let [p1, p2] = act.rest_pressures(p.supply_pressure, p.tank_pressure);
                self.s.x = vec![p.initial_position, 0.0, p1, p2];
            }
            self.act = Some(act);
        }
        self.act.as_ref().ok_or_else(|| "no actuator".to_string())
    }

    fn derivatives(act: &Actuator, p: &Params, inputs: [f64; 3], x: &[f64], dx: &mut [f64]) {
        let fluid = fluid_in_use(p);
        let air = p.has(Effect::EntrainedAir);
        let pr = [x[2], x[3]];
        dx[0] = x[1];
        dx[1] = act.motion(x[0], x[1], pr, inputs[2]).acceleration;
        let dp = act.pressure_derivatives(
            x[0],
            x[1],
            pr,
            [inputs[0], inputs[1]],
            p.tank_pressure,
            |q| oil_stiffness(&fluid, air, q),
        );
        dx[2..4].copy_from_slice(&dp);
    }

    /// What the chambers offer the manifold for carrying their pressures over a step:
    /// the flows that leave them at constant pressure (piston displacement and leakage),
    /// their volumes and bulk moduli, dP_i/dt = beta_i/V_i (Q_i - Q_displaced,i).
    fn chamber_coupling(act: &Actuator, p: &Params, x: &[f64]) -> [f64; 6] {
        let fluid = fluid_in_use(p);
        let air = p.has(Effect::EntrainedAir);
        let pr = [x[2], x[3]];
        let (q12, qf) = act.leakage(pr, p.tank_pressure);
        let vol = act.chamber_volumes(x[0]);
        let av = act.area * x[1];
        [
            q12 + qf[0] + av,
            -q12 + qf[1] - av,
            vol[0],
            vol[1],
            oil_stiffness(&fluid, air, pr[0]),
            oil_stiffness(&fluid, air, pr[1]),
        ]
    }
}

impl Model for ActuatorFmu {
    type Snapshot = Snapshot;

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

    fn variables() -> Vec<VarDef<Self>> {
        let d = default_params();
        let mut v = vec![
            real_input(
                "Q1",
                "Flow into chamber 1",
                "m3/s",
                0.0,
                (None, None),
                |m: &Self| m.s.inputs[0],
                |m, x| m.s.inputs[0] = x,
            ),
            real_input(
                "Q2",
                "Flow into chamber 2",
                "m3/s",
                0.0,
                (None, None),
                |m: &Self| m.s.inputs[1],
                |m, x| m.s.inputs[1] = x,
            ),
            real_input(
                "F_ext",
                "External force on the rod, opposing positive y",
                "N",
                0.0,
                FORCE_INPUT,
                |m: &Self| m.s.inputs[2],
                |m, x| m.s.inputs[2] = x,
            ),
            real_output(
                "P1",
                "Pressure in chamber 1 (absolute)",
                "Pa",
                |m: &Self| m.out[0],
            )
            .depends_on(&[]),
            real_output(
                "P2",
                "Pressure in chamber 2 (absolute)",
                "Pa",
                |m: &Self| m.out[1],
            )
            .depends_on(&[]),
            real_output("y", "Piston position from mid stroke", "m", |m: &Self| {
                m.out[2]
            })
            .depends_on(&[]),
            real_output("v", "Piston velocity", "m/s", |m: &Self| m.out[3]).depends_on(&[]),
            real_output("a", "Piston acceleration", "m/s2", |m: &Self| m.out[4])
                .depends_on(&["F_ext"]),
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
        fn out<const K: usize>(m: &ActuatorFmu) -> f64 {
            m.out[K]
        }
        let getters: [RealGetter<Self>; 6] =
            [out::<5>, out::<6>, out::<7>, out::<8>, out::<9>, out::<10>];
        v.extend(
            CHAMBER_OUTPUTS
                .iter()
                .zip(getters)
                .map(|(&(name, d, unit), get)| real_output(name, d, unit, get).depends_on(&[])),
        );
        fn get<const K: usize>(m: &ActuatorFmu) -> f64 {
            m.s.passages[K]
        }
        fn set<const K: usize>(m: &mut ActuatorFmu, x: f64) {
            m.s.passages[K] = x;
        }
        let access: [(RealGetter<Self>, RealSetter<Self>); 10] = [
            (get::<0>, set::<0>),
            (get::<1>, set::<1>),
            (get::<2>, set::<2>),
            (get::<3>, set::<3>),
            (get::<4>, set::<4>),
            (get::<5>, set::<5>),
            (get::<6>, set::<6>),
            (get::<7>, set::<7>),
            (get::<8>, set::<8>),
            (get::<9>, set::<9>),
        ];
        v.extend(port_inputs(&PASSAGE_INPUTS, access));
        v.push(super::fixed_step_parameter());
        v
    }

    fn instantiate(resources: Option<&Path>) -> Result<Self, String> {
        let params = load_params(resources, default_params())?;
        Ok(ActuatorFmu {
            s: Snapshot {
                params,
                x: vec![],
                inputs: [0.0; 3],
                t: 0.0,
                passages: [0.0; 10],
            },
            act: None,
            out: [0.0; 11],
        })
    }

    fn initialize(&mut self, start_time: f64) -> Result<(), String> {
        self.s.t = start_time;
        self.s.x.clear();
        self.act = None;
        self.refresh()
    }

    fn refresh(&mut self) -> Result<(), String> {
        self.actuator()?;
        let act = self.act.as_ref().ok_or("no actuator")?;
        let mut dx = [0.0; 4];
        Self::derivatives(act, &self.s.params, self.s.inputs, &self.s.x, &mut dx);
        let x = &self.s.x;
        let [qd1, qd2, v1, v2, b1, b2] = Self::chamber_coupling(act, &self.s.params, x);
        self.out = [x[2], x[3], x[0], x[1], dx[1], qd1, qd2, v1, v2, b1, b2];
        Ok(())
    }

    fn do_step(&mut self, h: f64) -> Result<(), String> {
        self.actuator()?;
        let act = self.act.as_ref().ok_or("no actuator")?;
        let p = &self.s.params;
        let inputs = self.s.inputs;
        let f = (p.solver.rtol / 1e-6).min(1.0);
        let mut atol = vec![1e-9 * f, 1e-6 * f, f, f];
        let mut scale = vec![1e-3, 1e-2, 1e6, 1e6];
        let mut x = self.s.x.clone();
        let [drive1, drive2, l1, l2, v1, v2, b1, b2, feed1, feed2] = self.s.passages;
        // With the manifold's passages connected, the chamber flows and the pressures of
        // the nodes behind them become states of this step,
        //   Q_i' = (P_i,drive - P_i) / L_i,   P_i,drive' = beta_i,drive/V_i,drive (Q_i,feed - Q_i),
        // so the passage answers the chamber pressure within the step and the loop of the
        // passage with the chamber is not left explicit (docs/cosim.md). L_i 0, the
        // default, holds the flow, as before.
        let carried = l1 > 0.0 || l2 > 0.0;
        let section = [(l1, v1, b1, feed1), (l2, v2, b2, feed2)];
        if carried {
            x.extend([inputs[0], inputs[1], drive1, drive2]);
            atol.extend([1e-8 * f, 1e-8 * f, f, f]);
            scale.extend([1e-5, 1e-5, 1e6, 1e6]);
        }
        let tol = Tolerances {
            rtol: p.solver.rtol,
            atol,
            fixed_step: p.solver.fixed_step,
        };
        integrate(
            |_t, x, dx| {
                if carried {
                    let inputs = [x[4], x[5], inputs[2]];
                    Self::derivatives(act, p, inputs, x, dx);
                    for (i, &(l, v, b, feed)) in section.iter().enumerate() {
                        let (q, drive) = (x[4 + i], x[6 + i]);
                        (dx[4 + i], dx[6 + i]) = if l > 0.0 {
                            let dd = if v > 0.0 { b / v * (feed - q) } else { 0.0 };
                            ((drive - x[2 + i]) / l, dd)
                        } else {
                            (0.0, 0.0)
                        };
                    }
                } else {
                    Self::derivatives(act, p, inputs, x, dx);
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
        x.truncate(4);
        self.s.x = x;
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
        if !s.x.is_empty() && s.x.len() != 4 {
            return Err("an actuator state has 4 values".into());
        }
        // y, v, P1, P2: finite, absolute pressures not negative (issue 16, item 7)
        if s.x.iter().any(|v| !v.is_finite()) || s.x.iter().skip(2).any(|p| *p < 0.0) {
            return Err(
                "the state holds a non-finite value or a negative absolute pressure".into(),
            );
        }
        self.s = s;
        self.act = None;
        self.refresh()
    }

    fn relative_tolerance(&mut self) -> Option<&mut f64> {
        Some(&mut self.params_mut().solver.rtol)
    }
}
