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
use crate::slave::{real_input, real_output, Model, ModelInfo, VarDef};

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
}

pub struct ActuatorFmu {
    s: Snapshot,
    act: Option<Actuator>,
    /// P1, P2, y, v, a
    out: [f64; 5],
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
}

impl Model for ActuatorFmu {
    type Snapshot = Snapshot;

    fn info() -> ModelInfo {
        ModelInfo {
            model_name: "HydroBench.Actuator",
            model_identifier: "actuator",
            description: "Double-rod actuator with hydrostatic bearings: chamber flows and external force in, pressures and motion out",
            default_experiment: DefaultExperiment { start_time: 0.0, stop_time: 0.1, tolerance: Some(1e-6), step_size: Some(1e-4) },
            enumerations: vec![],
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
            },
            act: None,
            out: [0.0; 5],
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
        self.out = [x[2], x[3], x[0], x[1], dx[1]];
        Ok(())
    }

    fn do_step(&mut self, h: f64) -> Result<(), String> {
        self.actuator()?;
        let act = self.act.as_ref().ok_or("no actuator")?;
        let p = &self.s.params;
        let inputs = self.s.inputs;
        let f = (p.solver.rtol / 1e-6).min(1.0);
        let tol = Tolerances {
            rtol: p.solver.rtol,
            atol: vec![1e-9 * f, 1e-6 * f, f, f],
        };
        let mut x = self.s.x.clone();
        integrate(
            |_t, x, dx| Self::derivatives(act, p, inputs, x, dx),
            &mut x,
            self.s.t,
            self.s.t + h,
            &tol,
            &[1e-3, 1e-2, 1e6, 1e6],
            &mut SolverStats::default(),
        )
        .map_err(|e| e.to_string())?;
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
        self.s = s;
        self.act = None;
        self.refresh()
    }
}
