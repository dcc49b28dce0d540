//! `controller.fmu`: the bench's position/pressure controllers (chapters 4-6).
//!
//! The master's communication step is the controller's sampling period: at each
//! communication point the law samples its inputs once and its commands are held over
//! the step. The model-based laws need velocity and acceleration: a DAO2 differentiator
//! estimates them from `y` (as on the bench), and a second one gives the reference's
//! derivatives from `y_ref`.

use std::path::Path;

use hbmodel::control::config::{ControllerParams, LawKind};
use hbmodel::control::dao2::Dao2;
use hbmodel::control::law::Reference;
use hbmodel::control::sampled::{SampledController, StateSource};
use hbmodel::control::scenario::law_name;
use hbmodel::control::Measurement;
use hbmodel::{Outputs, Params};
use modeldesc::DefaultExperiment;
use serde::{Deserialize, Serialize};

use super::{load_params, PRESSURE_INPUT};
use crate::slave::{
    boolean_parameter, enum_parameter, real_input, real_output, real_parameter, Model, ModelInfo,
    VarDef,
};

/// Bounds of the measured position (m): the longest stroke the parameters allow is 1 m,
/// so +-1 m holds any reading of a real LVDT; beyond, the input is a unit or wiring
/// error (y = 1e200 made the laws' commands NaN, issue 16).
const MEASURED_POSITION: (Option<f64>, Option<f64>) = (Some(-1.0), Some(1.0));

/// Bounds of the reference's derivatives: the thesis's moves peak at 0.2 m/s, 10 m/s2
/// and 131 m/s3; these are 50, 1000 and 1e5 times that, far beyond any trajectory the
/// 19 L/min valves can follow (0.67 m/s), yet keeping the laws' arithmetic finite.
const REFERENCE_SPEED: f64 = 10.0;
const REFERENCE_ACCELERATION: f64 = 1e4;
const REFERENCE_JERK: f64 = 1.31e7;

/// Laws in the order of their `law` values (1-based).
const LAWS: [(LawKind, &str, &str); 5] = [
    (
        LawKind::Proportional,
        law_name(LawKind::Proportional),
        "u1 = -u2 = Kp (y_ref - y), (4.22)",
    ),
    (
        LawKind::YLambda,
        law_name(LawKind::YLambda),
        "Backstepping Y-lambda, (5.16)-(5.35)",
    ),
    (
        LawKind::PY,
        law_name(LawKind::PY),
        "Backstepping P-Y, (5.36)-(5.58); P_ref is P1d",
    ),
    (
        LawKind::ModelFree,
        law_name(LawKind::ModelFree),
        "Model-free i-PI, (6.6)-(6.9)",
    ),
    (
        LawKind::RestrictedModel,
        law_name(LawKind::RestrictedModel),
        "Control with restricted model, (6.10)-(6.17)",
    ),
];

/// The `law` value of a law in the FMUs (1-based, the order of `LAWS`).
pub fn law_code(k: LawKind) -> i32 {
    LAWS.iter()
        .position(|(l, _, _)| *l == k)
        .map_or(1, |i| i as i32 + 1)
}

fn law_from(code: i32) -> LawKind {
    LAWS.get((code - 1).max(0) as usize)
        .map_or(LawKind::Proportional, |l| l.0)
}

/// Fraction of the sampling period by which a communication point may miss a sample
/// instant and still take it: the rounding of a time summed from decimal steps.
const SAMPLE_SLACK: f64 = 1e-6;

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ControllerFmu {
    cp: ControllerParams,
    /// y_ref, y, P1, P2, P_ref, dy_ref, d2y_ref, d3y_ref
    pub(crate) inputs: [f64; 8],
    /// Take the reference's derivatives from the inputs instead of a DAO2 on y_ref.
    derivatives_given: bool,
    /// Sample at the law's own period (`cp.period`) and hold between samples, instead of
    /// at every communication point.
    self_sampled: bool,
    /// With `self_sampled`: the first instant of the next sample (s).
    next_sample: f64,
    /// The bench the laws' control model (II.1)-(II.2) is written for: the shipped
    /// parameter file, or the plant's own parameters inside bench_closed_loop.fmu. The
    /// payload stays unknown to the laws (chapter 7).
    pub(crate) plant: Params,
    pub(crate) out: [f64; 2],
    t: f64,
    controller: Option<SampledController>,
    reference: Dao2,
    /// The sample taken at the current time: its inputs and the memories before it, so
    /// that inputs set again at the same instant (Jacobi masters) replace it cleanly.
    sample: Option<(f64, [f64; 8], Option<SampledController>, Dao2)>,
}

impl ControllerFmu {
    fn fresh(cp: ControllerParams, derivatives_given: bool, plant: Params) -> Self {
        let self_sampled = false;
        ControllerFmu {
            reference: Dao2::new(cp.dao2[0], cp.dao2[1], cp.period),
            cp,
            // mid stroke, chambers near half supply, the thesis's 80 bar pressure reference
            inputs: [0.0, 0.0, 1e7, 1e7, 80e5, 0.0, 0.0, 0.0],
            derivatives_given,
            self_sampled,
            next_sample: 0.0,
            plant,
            out: [0.0; 2],
            t: 0.0,
            controller: None,
            sample: None,
        }
    }
}

impl Model for ControllerFmu {
    type Snapshot = ControllerFmu;

    fn info() -> ModelInfo {
        ModelInfo {
            model_name: "HydroBench.Controller",
            model_identifier: "controller",
            description: "Position/pressure controllers of the bench (chapters 4-6), sampled at the communication step",
            default_experiment: DefaultExperiment { start_time: 0.0, stop_time: 0.1, tolerance: None, step_size: Some(1e-3) },
            equations: &[
                "(4.22) proportional; (5.16)-(5.35) Y-lambda; (5.36)-(5.58) P-Y",
                "(6.6)-(6.9) model-free i-PI; (6.10)-(6.17) restricted model",
                "(5.59)-(5.63) DAO2 differentiator for the velocity and acceleration",
                "commands saturated at +-10 V",
            ],
            parameters: None,
        }
    }

    fn variables() -> Vec<VarDef<Self>> {
        let d = ControllerParams::default();
        let gain = |name: &'static str, k: usize| {
            real_parameter(
                name,
                "Backstepping gain",
                "1/s",
                d.c[k],
                0.0,
                1e5,
                move |m: &Self| m.cp.c[k],
                move |m: &mut Self, x| m.cp.c[k] = x,
            )
        };
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
                MEASURED_POSITION,
                |m: &Self| m.inputs[1],
                |m, x| m.inputs[1] = x,
            ),
            real_input(
                "P1",
                "Measured pressure in chamber 1",
                "Pa",
                1e7,
                PRESSURE_INPUT,
                |m: &Self| m.inputs[2],
                |m, x| m.inputs[2] = x,
            ),
            real_input(
                "P2",
                "Measured pressure in chamber 2",
                "Pa",
                1e7,
                PRESSURE_INPUT,
                |m: &Self| m.inputs[3],
                |m, x| m.inputs[3] = x,
            ),
            real_input(
                "P_ref",
                "Pressure reference: P0 of Y-lambda, P1d of P-Y",
                "Pa",
                80e5,
                PRESSURE_INPUT,
                |m: &Self| m.inputs[4],
                |m, x| m.inputs[4] = x,
            ),
            real_input(
                "dy_ref",
                "Velocity of the position reference (used when reference_derivatives is true)",
                "m/s",
                0.0,
                (Some(-REFERENCE_SPEED), Some(REFERENCE_SPEED)),
                |m: &Self| m.inputs[5],
                |m, x| m.inputs[5] = x,
            ),
            real_input(
                "d2y_ref",
                "Acceleration of the position reference (used when reference_derivatives is true)",
                "m/s2",
                0.0,
                (Some(-REFERENCE_ACCELERATION), Some(REFERENCE_ACCELERATION)),
                |m: &Self| m.inputs[6],
                |m, x| m.inputs[6] = x,
            ),
            real_input(
                "d3y_ref",
                "Jerk of the position reference (used when reference_derivatives is true)",
                "m/s3",
                0.0,
                (Some(-REFERENCE_JERK), Some(REFERENCE_JERK)),
                |m: &Self| m.inputs[7],
                |m, x| m.inputs[7] = x,
            ),
            boolean_parameter(
                "reference_derivatives",
                "true: the laws take the reference's velocity, acceleration and jerk from the inputs \
                 dy_ref, d2y_ref, d3y_ref (a trajectory generator knows them exactly); false: a DAO2 \
                 differentiator estimates velocity and acceleration from y_ref, with its lag, and the jerk is 0",
                false,
                |m: &Self| m.derivatives_given,
                |m: &mut Self, on| m.derivatives_given = on,
            ),
            real_output(
                "u1",
                "Command of SV1, saturated at +-10 V",
                "V",
                |m: &Self| m.out[0],
            ),
            real_output(
                "u2",
                "Command of SV2, saturated at +-10 V",
                "V",
                |m: &Self| m.out[1],
            ),
            enum_parameter(
                "law",
                "Control law",
                &LAWS.map(|(_, name, meaning)| (name, meaning)),
                1,
                |m: &Self| law_code(m.cp.law),
                |m, k| m.cp.law = law_from(k),
            ),
            real_parameter(
                "Kp",
                "Proportional gain of (4.22)",
                "V/m",
                d.kp,
                0.0,
                1e6,
                |m: &Self| m.cp.kp,
                |m: &mut Self, x| m.cp.kp = x,
            ),
            gain("c1", 0),
            gain("c2", 1),
            gain("c3", 2),
            gain("c4", 3),
            real_parameter(
                "lambda",
                "Weight of the Y-lambda pressure combination",
                "",
                d.lambda,
                0.0,
                1.0,
                |m: &Self| m.cp.lambda,
                |m: &mut Self, x| m.cp.lambda = x,
            ),
            real_parameter(
                "Kp_model_free",
                "Proportional gain of the model-free and restricted-model laws",
                "V/m",
                d.kp_model_free,
                0.0,
                1e5,
                |m: &Self| m.cp.kp_model_free,
                |m: &mut Self, x| m.cp.kp_model_free = x,
            ),
            real_parameter(
                "Kd0",
                "DAO2 gain Kd0",
                "1/s",
                d.dao2[0],
                1.0,
                1e5,
                |m: &Self| m.cp.dao2[0],
                |m: &mut Self, x| m.cp.dao2[0] = x,
            ),
            real_parameter(
                "Kd1",
                "DAO2 gain Kd1",
                "1/s",
                d.dao2[1],
                1.0,
                1e5,
                |m: &Self| m.cp.dao2[1],
                |m: &mut Self, x| m.cp.dao2[1] = x,
            ),
            boolean_parameter(
                "self_sampled",
                "true: the law samples at its own 1 ms period (the bench's 1 kHz acquisition) and \
                 holds its commands in between, whatever the master's communication step (for \
                 single-rate engines: OMSimulator, libcosim); false: it samples at every \
                 communication point",
                false,
                |m: &Self| m.self_sampled,
                |m: &mut Self, on| m.self_sampled = on,
            ),
        ]
    }

    fn instantiate(resources: Option<&Path>) -> Result<Self, String> {
        let plant = load_params(resources, super::bench::default_params())?;
        Ok(Self::fresh(ControllerParams::default(), false, plant))
    }

    fn initialize(&mut self, start_time: f64) -> Result<(), String> {
        let (inputs, self_sampled) = (self.inputs, self.self_sampled);
        // parameters are final: build the law on the thesis bench's control model
        let mut cp = self.cp;
        cp.source = StateSource::Dao2;
        *self = Self::fresh(cp, self.derivatives_given, self.plant.clone());
        self.inputs = inputs;
        self.reference.reset(inputs[0]);
        self.self_sampled = self_sampled;
        self.t = start_time;
        self.next_sample = start_time;
        self.controller = Some(cp.controller(&self.plant));
        self.refresh()
    }

    fn refresh(&mut self) -> Result<(), String> {
        let same_instant = self.sample.as_ref().is_some_and(|s| s.0 == self.t);
        // between its own sample instants a self-sampled controller holds its commands
        // (a communication point within SAMPLE_SLACK of an instant counts as on it)
        if self.self_sampled
            && !same_instant
            && self.t < self.next_sample - SAMPLE_SLACK * self.cp.period
        {
            return Ok(());
        }
        if self.self_sampled && !same_instant {
            let k = ((self.t - self.next_sample) / self.cp.period + SAMPLE_SLACK).floor();
            self.next_sample += (k + 1.0) * self.cp.period;
        }
        if let Some((t, used, ctrl, reference)) = &self.sample {
            if *t == self.t && *used == self.inputs {
                return Ok(());
            }
            if *t == self.t {
                // inputs changed at the same instant: undo that sample
                self.controller = ctrl.clone();
                self.reference = reference.clone();
            }
        }
        self.sample = Some((
            self.t,
            self.inputs,
            self.controller.clone(),
            self.reference.clone(),
        ));
        let [y_ref, y, p1, p2, p_ref, dy, d2y, d3y] = self.inputs;
        let estimated = self.reference.update(y_ref);
        let reference = Reference {
            // the DAO2 on y_ref gives no jerk: the laws then run without that feedforward
            y: if self.derivatives_given {
                [y_ref, dy, d2y, d3y]
            } else {
                [y_ref, estimated[1], estimated[2], 0.0]
            },
            p: [p_ref, 0.0],
        };
        let sensed = Measurement { y, p1, p2 };
        let ctrl = self
            .controller
            .as_mut()
            .ok_or("the controller is not initialized")?;
        self.out = ctrl.sample(self.t, &reference, &sensed, &Outputs::default());
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
        self.clone()
    }

    fn restore(&mut self, s: Self) -> Result<(), String> {
        *self = s;
        Ok(())
    }
}
