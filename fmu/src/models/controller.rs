//! `controller.fmu`: the bench's position controller, u1 = -u2 = Kp (y_ref - y).
//!
//! The master's communication step is the controller's sampling period: outputs are
//! computed from the inputs of the current communication point and held over the step.

use std::path::Path;

use hbmodel::control::{Controller, Measurement, Proportional};
use modeldesc::{DefaultExperiment, EnumItem, EnumerationType};
use serde::{Deserialize, Serialize};

use crate::slave::{
    enum_parameter, real_input, real_output, real_parameter, Model, ModelInfo, VarDef,
};

/// Section 4.4's proportional gain (V/m).
pub const THESIS_KP: f64 = 1169.0;

#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct ControllerFmu {
    law: i32,
    kp: f64,
    /// y_ref, y, P1, P2, P_ref
    inputs: [f64; 5],
    out: [f64; 2],
    t: f64,
}

impl Model for ControllerFmu {
    type Snapshot = ControllerFmu;

    fn info() -> ModelInfo {
        ModelInfo {
            model_name: "HydroBench.Controller",
            model_identifier: "controller",
            description:
                "Position/pressure controller of the bench (proportional control of section 4.4)",
            default_experiment: DefaultExperiment {
                start_time: 0.0,
                stop_time: 0.1,
                tolerance: None,
                step_size: Some(1e-3),
            },
            enumerations: vec![EnumerationType {
                name: "HydroBench.ControlLaw".into(),
                description: "Control law".into(),
                items: vec![EnumItem {
                    name: "proportional".into(),
                    value: 1,
                    description: "u1 = -u2 = Kp (y_ref - y), (4.22)".into(),
                }],
            }],
            equations: &["(4.22) u1 = -u2 = Kp (y_ref - y), saturated at +-10 V"],
            parameters: None,
        }
    }

    fn variables() -> Vec<VarDef<Self>> {
        vec![
            real_input(
                "y_ref",
                "Position reference",
                "m",
                0.0,
                (Some(-0.15), Some(0.15)),
                |m: &Self| m.inputs[0],
                |m, x| m.inputs[0] = x,
            ),
            real_input(
                "y",
                "Measured piston position",
                "m",
                0.0,
                (None, None),
                |m: &Self| m.inputs[1],
                |m, x| m.inputs[1] = x,
            ),
            real_input(
                "P1",
                "Measured pressure in chamber 1",
                "Pa",
                1e7,
                (None, None),
                |m: &Self| m.inputs[2],
                |m, x| m.inputs[2] = x,
            ),
            real_input(
                "P2",
                "Measured pressure in chamber 2",
                "Pa",
                1e7,
                (None, None),
                |m: &Self| m.inputs[3],
                |m, x| m.inputs[3] = x,
            ),
            real_input(
                "P_ref",
                "Pressure reference (used by the pressure laws)",
                "Pa",
                80e5,
                (None, None),
                |m: &Self| m.inputs[4],
                |m, x| m.inputs[4] = x,
            ),
            real_output(
                "u1",
                "Command of SV1, saturated at +-10 V",
                "V",
                |m: &Self| m.out[0],
            )
            .depends_on(&["y_ref", "y"]),
            real_output(
                "u2",
                "Command of SV2, saturated at +-10 V",
                "V",
                |m: &Self| m.out[1],
            )
            .depends_on(&["y_ref", "y"]),
            enum_parameter(
                "law",
                "Control law",
                "HydroBench.ControlLaw",
                1,
                1,
                1,
                |m: &Self| m.law,
                |m, k| m.law = k,
            ),
            real_parameter(
                "Kp",
                "Proportional gain",
                "V/m",
                THESIS_KP,
                0.0,
                1e6,
                |m: &Self| m.kp,
                |m: &mut Self, x| m.kp = x,
            ),
        ]
    }

    fn instantiate(_resources: Option<&Path>) -> Result<Self, String> {
        Ok(ControllerFmu {
            law: 1,
            kp: THESIS_KP,
            inputs: [0.0, 0.0, 1e7, 1e7, 80e5],
            out: [0.0; 2],
            t: 0.0,
        })
    }

    fn initialize(&mut self, start_time: f64) -> Result<(), String> {
        self.t = start_time;
        self.refresh()
    }

    fn refresh(&mut self) -> Result<(), String> {
        let m = Measurement {
            y: self.inputs[1],
            p1: self.inputs[2],
            p2: self.inputs[3],
        };
        self.out = Proportional { kp: self.kp }.update(self.t, self.inputs[0], &m);
        Ok(())
    }

    fn do_step(&mut self, h: f64) -> Result<(), String> {
        self.t += h;
        Ok(())
    }

    fn time(&self) -> f64 {
        self.t
    }

    fn snapshot(&self) -> Self {
        *self
    }

    fn restore(&mut self, s: Self) -> Result<(), String> {
        *self = s;
        Ok(())
    }
}
