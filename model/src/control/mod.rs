//! Sampled controllers around the bench and the loop that runs them.
//!
//! The bench's dSPACE board samples at 1 kHz and holds its outputs between samples
//! (zero-order hold); with the `sensor_delay` effect on, the controller sees the plant as
//! it was `sensors.delay` seconds before each sample. The thesis's other laws (issue 5)
//! implement the same [`Controller`] trait.

pub mod backstepping;
pub mod config;
pub mod dao2;
pub mod law;
pub mod model_free;
pub mod sampled;
pub mod scenario;
pub mod signal;
pub mod trajectory;

use crate::bench::{Inputs, Outputs, Simulation};
use crate::effects::Effect;
use crate::sensors::DelayLine;
use crate::solver::SolverError;

/// Sampling period of the bench's controller board (s), section 4.4.
pub const SAMPLE_PERIOD: f64 = 1e-3;

/// Saturation of the servovalve commands (V): the D765's rated input.
pub const COMMAND_LIMIT: f64 = 10.0;

// What the controller receives at a sample: declared with the sensors that deliver it.
pub use crate::sensors::Measurement;

impl Measurement {
    /// The sensed signals of the bench's outputs.
    pub fn of(o: &Outputs) -> Self {
        Measurement {
            y: o.y,
            p1: o.p1,
            p2: o.p2,
        }
    }
}

/// A discrete-time controller: at each sample, the measurement and the reference in,
/// the two valve commands out.
pub trait Controller {
    fn update(&mut self, t: f64, reference: f64, m: &Measurement) -> [f64; 2];
}

/// Proportional position control u1 = -u2 = Kp (yd - y) (section 4.4), saturated.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Proportional {
    pub kp: f64,
}

impl Controller for Proportional {
    fn update(&mut self, _t: f64, reference: f64, m: &Measurement) -> [f64; 2] {
        let u = (self.kp * (reference - m.y)).clamp(-COMMAND_LIMIT, COMMAND_LIMIT);
        [u, -u]
    }
}

impl law::Law for Proportional {
    fn commands(
        &mut self,
        _t: f64,
        r: &law::Reference,
        x: &law::Estimate,
        _period: f64,
    ) -> [f64; 2] {
        let u = self.kp * (r.y[0] - x.y);
        [u, -u]
    }
}

/// Run a sampled law on `sim` following `trajectory` up to `t_end`.
pub fn run_sampled(
    sim: &mut Simulation,
    controller: &mut sampled::SampledController,
    trajectory: &dyn Fn(f64) -> law::Reference,
    t_end: f64,
    timing: &Timing,
) -> Result<Vec<Sample>, SolverError> {
    run_loop(
        sim,
        &mut |t, sensed, exact| controller.sample(t, &trajectory(t), sensed, exact),
        &|t| trajectory(t).y[0],
        t_end,
        timing,
    )
}

/// One recorded instant of a closed-loop run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    pub t: f64,
    pub reference: f64,
    pub inputs: Inputs,
    pub out: Outputs,
}

/// Run `controller` on `sim` from its current time to `t_end`, sampling every `period`,
/// recording the plant after each sample interval (and `substeps` times within it).
pub fn run_closed_loop(
    sim: &mut Simulation,
    controller: &mut dyn Controller,
    reference: &dyn Fn(f64) -> f64,
    t_end: f64,
    period: f64,
    substeps: usize,
) -> Result<Vec<Sample>, SolverError> {
    let timing = Timing {
        period,
        substeps,
        computation_delay: 0.0,
    };
    run_loop(
        sim,
        &mut |t, m, _exact| controller.update(t, reference(t), m),
        reference,
        t_end,
        &timing,
    )
}

/// When a sampled controller reads and acts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timing {
    /// Sampling period (s).
    pub period: f64,
    /// Recorded points per period.
    pub substeps: usize,
    /// Time between a sample and the command it produces reaching the valves (s), less
    /// than a period: the board's computation time.
    pub computation_delay: f64,
}

/// The sampled loop: at each sample `decide(t, sensed, exact)` gives the commands from
/// the sensed measurement (delayed when `sensor_delay` is on) or the exact outputs; they
/// reach the valves `computation_delay` later and are held until the next ones.
pub fn run_loop(
    sim: &mut Simulation,
    decide: &mut dyn FnMut(f64, &Measurement, &Outputs) -> [f64; 2],
    reference: &dyn Fn(f64) -> f64,
    t_end: f64,
    timing: &Timing,
) -> Result<Vec<Sample>, SolverError> {
    let period = timing.period;
    let params = sim.bench().params();
    let delay = if params.has(Effect::SensorDelay) {
        params.sensors.delay
    } else {
        0.0
    };
    let compute = timing.computation_delay.clamp(0.0, period);
    let mut trace = Vec::new();
    let mut sensed = DelayLine::new(delay, sim.time(), Measurement::of(&sim.outputs()));
    let n = ((t_end - sim.time()) / period).round() as usize;
    let t0 = sim.time();
    let f_ext = sim.inputs().f_ext;
    let mut applied = [sim.inputs().u1, sim.inputs().u2];
    for k in 0..n {
        let t_k = t0 + k as f64 * period;
        let m = sensed.read(t_k);
        let u = decide(t_k, &m, &sim.outputs());
        let substeps = timing.substeps.max(1);
        let mut points: Vec<f64> = (1..=substeps)
            .map(|j| t_k + period * j as f64 / substeps as f64)
            .collect();
        if let Some(t_read) = sensed.read_instant_within(t_k, t_k + period) {
            points.push(t_read);
        }
        let t_act = t_k + compute;
        if compute > 0.0 && t_act < t_k + period {
            points.push(t_act);
        } else {
            applied = u;
        }
        points.sort_by(f64::total_cmp);
        points.dedup_by(|a, b| (*a - *b).abs() < 1e-9 * period);
        for t in points {
            sim.set_inputs(Inputs {
                u1: applied[0],
                u2: applied[1],
                f_ext,
            });
            sim.advance_to(t)?;
            if (t - t_act).abs() < 1e-9 * period {
                applied = u;
            }
            let out = sim.outputs();
            sensed.record(t, Measurement::of(&out));
            trace.push(Sample {
                t,
                reference: reference(t),
                inputs: sim.inputs(),
                out,
            });
        }
        sensed.forget_before(t_k - 2.0 * period);
    }
    Ok(trace)
}

/// 95 % response time of a step recorded in `trace` that starts at `t_step` from
/// `from` to `to`: the last time the position was outside the 5 % band around `to`.
pub fn response_time_95(trace: &[Sample], t_step: f64, from: f64, to: f64) -> Option<f64> {
    let band = 0.05 * (to - from).abs();
    let last_out = trace
        .iter()
        .filter(|s| s.t >= t_step)
        .filter(|s| (s.out.y - to).abs() > band)
        .map(|s| s.t)
        .fold(None, |acc: Option<f64>, t| {
            Some(acc.map_or(t, |a| a.max(t)))
        });
    last_out.map(|t| t - t_step)
}

/// Closed-loop amplitude ratio |Y/Yref| of the first harmonic for a sine reference of
/// `amplitude` (m) at `frequency` (Hz) under proportional control `kp` (V/m), after the
/// transient has settled (4 cycles or 30 ms), over 6 cycles.
pub fn sine_amplitude_ratio(
    params: &crate::params::Params,
    kp: f64,
    amplitude: f64,
    frequency: f64,
) -> Result<f64, crate::params::ParamError> {
    use std::f64::consts::PI;
    let mut sim = Simulation::new(params)?;
    let settle = (4.0 / frequency).max(0.03);
    let w = 2.0 * PI * frequency;
    let reference = move |t: f64| amplitude * (w * t).sin();
    let trace = run_closed_loop(
        &mut sim,
        &mut Proportional { kp },
        &reference,
        settle + 6.0 / frequency,
        SAMPLE_PERIOD,
        4,
    )
    .map_err(|e| crate::params::ParamError {
        file: "<simulation>".into(),
        line: None,
        field: None,
        message: e.to_string(),
    })?;
    let (mut s, mut c, mut n) = (0.0, 0.0, 0.0);
    for k in trace.iter().filter(|k| k.t > settle) {
        s += k.out.y * (w * k.t).sin();
        c += k.out.y * (w * k.t).cos();
        n += 1.0;
    }
    Ok(2.0 * s.hypot(c) / n / amplitude)
}
