//! `bench_closed_loop.fmu`: the bench and its controller in one FMU.
//!
//! At each communication point the controller samples the plant (y, P1, P2) and the
//! references, and its commands drive the plant over the step: the same exchange a
//! master does between `controller.fmu` and `bench.fmu`, inside one instance, with the
//! parameters of both.

use std::path::Path;

use modeldesc::DefaultExperiment;
use serde::{Deserialize, Serialize};

use super::bench::BenchFmu;
use super::controller::ControllerFmu;
use super::HasParams;
use crate::slave::{project, Model, ModelInfo, VarDef};

pub struct ClosedLoopFmu {
    plant: BenchFmu,
    controller: ControllerFmu,
}

#[derive(Clone, Serialize, Deserialize)]
pub struct Snapshot {
    plant: <BenchFmu as Model>::Snapshot,
    controller: ControllerFmu,
}

/// Plant inputs the controller drives, and controller inputs the plant feeds: they are
/// internal to the closed loop, so the FMU does not declare them.
const PLANT_INTERNAL: [&str; 2] = ["u1", "u2"];
const CONTROLLER_INTERNAL: [&str; 3] = ["y", "P1", "P2"];

impl ClosedLoopFmu {
    /// Exchange at the current instant: the controller samples the plant, the plant
    /// takes the commands.
    fn couple(&mut self) -> Result<(), String> {
        self.plant.refresh()?;
        // the controller reads the acquisition, delayed when sensor_delay is on
        let m = self.plant.measured;
        self.controller.inputs[1..4].copy_from_slice(&[m.y, m.p1, m.p2]);
        self.controller.refresh()?;
        let [u1, u2] = self.controller.out;
        self.plant.inputs.u1 = u1;
        self.plant.inputs.u2 = u2;
        self.plant.refresh()
    }
}

impl Model for ClosedLoopFmu {
    type Snapshot = Snapshot;

    fn info() -> ModelInfo {
        ModelInfo {
            model_name: "HydroBench.BenchClosedLoop",
            model_identifier: "bench_closed_loop",
            description: "The bench and its controller in one FMU: references in, motion, pressures and commands out",
            default_experiment: DefaultExperiment { start_time: 0.0, stop_time: 0.2, tolerance: Some(1e-6), step_size: Some(1e-3) },
            equations: &[
                "the bench: (II.2), (3.1)-(3.7), (4.1)-(4.13), (A.7)-(A.16)",
                "the controller: (4.22), (5.16)-(5.58), (5.59)-(5.63), (6.6)-(6.17)",
                "the controller samples the plant at each communication point",
            ],
            parameters: BenchFmu::info().parameters,
        }
    }

    fn variables() -> Vec<VarDef<Self>> {
        let mut v: Vec<VarDef<Self>> = BenchFmu::variables()
            .into_iter()
            .filter(|x| !PLANT_INTERNAL.contains(&x.decl.name.as_str()))
            .map(|x| project(x, |m: &Self| &m.plant, |m: &mut Self| &mut m.plant))
            .collect();
        // the plant's fixed step goes last, after the controller's variables, so that
        // every value reference from before the real-time mode keeps its number
        let fixed_step = v
            .iter()
            .position(|x| x.decl.name == super::FIXED_STEP)
            .map(|i| v.remove(i));
        v.extend(
            ControllerFmu::variables()
                .into_iter()
                .filter(|x| !CONTROLLER_INTERNAL.contains(&x.decl.name.as_str()))
                .map(|x| {
                    project(
                        x,
                        |m: &Self| &m.controller,
                        |m: &mut Self| &mut m.controller,
                    )
                }),
        );
        // outputs that followed the commands now follow the references through the
        // controller: leave their dependencies to the default (all inputs)
        for var in &mut v {
            if var
                .depends_on
                .is_some_and(|d| d.iter().any(|n| PLANT_INTERNAL.contains(n)))
            {
                var.depends_on = None;
            }
        }
        v.extend(fixed_step);
        v
    }

    fn instantiate(resources: Option<&Path>) -> Result<Self, String> {
        Ok(ClosedLoopFmu {
            plant: BenchFmu::instantiate(resources)?,
            controller: ControllerFmu::instantiate(resources)?,
        })
    }

    fn initialize(&mut self, start_time: f64) -> Result<(), String> {
        self.plant.initialize(start_time)?;
        // the laws are written for this plant (its payload stays unknown to them)
        self.controller.plant = self.plant.params().clone();
        self.controller.initialize(start_time)?;
        self.couple()
    }

    fn refresh(&mut self) -> Result<(), String> {
        self.couple()
    }

    fn do_step(&mut self, h: f64) -> Result<(), String> {
        self.couple()?;
        self.plant.do_step(h)?;
        self.controller.do_step(h)
    }

    fn time(&self) -> f64 {
        self.plant.time()
    }

    fn snapshot(&self) -> Snapshot {
        Snapshot {
            plant: self.plant.snapshot(),
            controller: self.controller.snapshot(),
        }
    }

    fn restore(&mut self, s: Snapshot) -> Result<(), String> {
        self.plant.restore(s.plant)?;
        self.controller.restore(s.controller)
    }

    fn relative_tolerance(&mut self) -> Option<&mut f64> {
        self.plant.relative_tolerance()
    }
}
