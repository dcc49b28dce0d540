//! `reference.fmu`: the thesis's reference signals as a signal source, so that a system of
//! FMUs (reference -> controller -> valves -> manifold -> actuator -> controller) runs a
//! whole experiment with no input from outside, in any co-simulation engine.
//!
//! The signals are the model's own (`hbmodel::control::scenario::Signal`, the 7th-order
//! moves of `trajectory`), evaluated at the FMU's time: y_ref with its first three
//! derivatives (the backstepping laws need them up to the jerk) and a constant P_ref.

use std::path::Path;

use hbmodel::control::backstepping::P_REF_THESIS;
use hbmodel::control::scenario::{
    Signal, SINE_AMPLITUDE, SINE_FREQUENCY, STEP_AMPLITUDE, STEP_TIMES,
};
use hbmodel::control::trajectory::{
    Trajectory, THESIS_FIRST_MOVE, THESIS_HALF_PERIOD, THESIS_HIGH, THESIS_LOW,
    THESIS_MOVE_DURATION,
};
use modeldesc::DefaultExperiment;

use crate::slave::{enum_parameter, real_output, real_parameter, Model, ModelInfo, VarDef};

/// The signals `signal` selects (name, meaning), values 1 to 5.
pub const SIGNALS: [(&str, &str); 5] = [
    (
        "moves",
        "7th-order moves from move.from to move.to and back, section 5.5",
    ),
    (
        "steps",
        "a step from steps.low to steps.high at steps.up and back at steps.down, Fig. 4.8",
    ),
    (
        "sine",
        "sine.amplitude sin(2 pi sine.frequency t), Figs. 4.9-4.14",
    ),
    (
        "sweep",
        "logarithmic sweep of amplitude sweep.amplitude from sweep.f_start to sweep.f_end",
    ),
    (
        "ramp",
        "constant-velocity ramp from ramp.from to ramp.to starting at ramp.start",
    ),
];

/// Position parameters' bounds (m): the controller's `y_ref` input range.
const POSITION: f64 = 0.15;
/// Lowest duration or frequency accepted (s, Hz): keeps every signal finite.
const TINY: f64 = 1e-6;
/// Sweep defaults: 1 to 100 Hz, the frequency range of Figs. 4.9-4.14, over 10 s, so that
/// each decade takes 5 s and the loop settles at each frequency as it passes.
const SWEEP_F_START: f64 = 1.0;
const SWEEP_F_END: f64 = 100.0;
const SWEEP_DURATION: f64 = 10.0;
/// Ramp duration default (s): the +-10 mm stroke of the moves in 1 s, 20 mm/s, a tenth of
/// the moves' peak speed, which a proportional loop follows with a small constant lag.
const RAMP_DURATION: f64 = 1.0;
/// Upper bound of the times and durations (s): an hour, far beyond any bench run.
const LONG: f64 = 3600.0;
/// Upper bound of the frequencies (Hz): beyond the servovalves' bandwidth by far.
/// (Frequencies are declared in 1/s, the SI unit of the model descriptions: cycles per second.)
const HIGH_FREQUENCY: f64 = 1e4;

/// A real parameter of the signals: name, description, unit, default, min, max.
type Spec = (&'static str, &'static str, &'static str, f64, f64, f64);

/// Every real parameter; the position of each is its index in `ReferenceFmu::values`.
const PARAMETERS: [Spec; 20] = [
    ("move.from", "Start position of the first move (moves)", "m", THESIS_LOW, -POSITION, POSITION),
    ("move.to", "End position of the first move (moves)", "m", THESIS_HIGH, -POSITION, POSITION),
    ("move.start", "Start time of the first move (moves)", "s", THESIS_FIRST_MOVE, 0.0, LONG),
    ("move.duration", "Duration of each move (moves)", "s", THESIS_MOVE_DURATION, TINY, LONG),
    ("move.half_period", "Time between the starts of a move and its return; the cycle repeats every two (moves)", "s", THESIS_HALF_PERIOD, TINY, LONG),
    ("steps.low", "Position before steps.up and after steps.down (steps)", "m", -STEP_AMPLITUDE, -POSITION, POSITION),
    ("steps.high", "Position between steps.up and steps.down (steps)", "m", STEP_AMPLITUDE, -POSITION, POSITION),
    ("steps.up", "Time of the step to steps.high (steps)", "s", STEP_TIMES[0], 0.0, LONG),
    ("steps.down", "Time of the step back to steps.low (steps)", "s", STEP_TIMES[1], 0.0, LONG),
    ("sine.amplitude", "Amplitude of the sine about mid stroke (sine)", "m", SINE_AMPLITUDE, 0.0, POSITION),
    ("sine.frequency", "Frequency of the sine (sine)", "1/s", SINE_FREQUENCY, TINY, HIGH_FREQUENCY),
    ("sweep.amplitude", "Amplitude of the sweep about mid stroke (sweep)", "m", SINE_AMPLITUDE, 0.0, POSITION),
    ("sweep.f_start", "Frequency at t = 0 (sweep)", "1/s", SWEEP_F_START, TINY, HIGH_FREQUENCY),
    ("sweep.f_end", "Frequency at sweep.duration, held after (sweep)", "1/s", SWEEP_F_END, TINY, HIGH_FREQUENCY),
    ("sweep.duration", "Duration of the sweep (sweep)", "s", SWEEP_DURATION, TINY, LONG),
    ("ramp.from", "Position before the ramp (ramp)", "m", THESIS_LOW, -POSITION, POSITION),
    ("ramp.to", "Position after the ramp (ramp)", "m", THESIS_HIGH, -POSITION, POSITION),
    ("ramp.start", "Start time of the ramp (ramp)", "s", THESIS_FIRST_MOVE, 0.0, LONG),
    ("ramp.duration", "Duration of the ramp (ramp)", "s", RAMP_DURATION, TINY, LONG),
    // the bench's 210 bar supply bounds any chamber pressure it can hold
    ("pressure", "Pressure reference given as P_ref: P0 of the Y-lambda law, P1d of the P-Y law (section 5.5)", "Pa", P_REF_THESIS, 0.0, 210e5),
];
/// Index of `pressure` in `PARAMETERS`.
const PRESSURE: usize = PARAMETERS.len() - 1;

#[derive(Debug, Clone)]
pub struct ReferenceFmu {
    /// 1-based index into `SIGNALS`.
    kind: i32,
    /// The real parameters, in the order of `PARAMETERS`.
    values: Vec<f64>,
    t: f64,
    /// Built from the parameters at initialization.
    signal: Option<Signal>,
    /// y_ref, dy_ref, d2y_ref, d3y_ref at `t`.
    out: [f64; 4],
}

impl ReferenceFmu {
    /// The selected signal with the current parameters.
    fn signal(&self) -> Result<Signal, String> {
        let v = |name: &str| {
            let k = PARAMETERS.iter().position(|s| s.0 == name);
            k.map_or(f64::NAN, |k| self.values[k])
        };
        Ok(match self.kind {
            1 => {
                let (a, b, t0, d, half) = (
                    v("move.from"),
                    v("move.to"),
                    v("move.start"),
                    v("move.duration"),
                    v("move.half_period"),
                );
                let moves = [(t0, a, b, d), (t0 + half, b, a, d)];
                Signal::Moves(Trajectory::repeating(&moves, 2.0 * half).map_err(|e| {
                    format!("move.duration and move.half_period make no cycle: {e}")
                })?)
            }
            2 => {
                let times = vec![v("steps.up"), v("steps.down")];
                if times[1] < times[0] {
                    return Err("steps.down comes before steps.up".into());
                }
                Signal::Steps {
                    low: v("steps.low"),
                    high: v("steps.high"),
                    times,
                }
            }
            3 => Signal::Sine {
                amplitude: v("sine.amplitude"),
                frequency: v("sine.frequency"),
            },
            4 => Signal::Sweep {
                amplitude: v("sweep.amplitude"),
                f_start: v("sweep.f_start"),
                f_end: v("sweep.f_end"),
                duration: v("sweep.duration"),
            },
            _ => Signal::Ramp {
                start: v("ramp.start"),
                from: v("ramp.from"),
                to: v("ramp.to"),
                duration: v("ramp.duration"),
            },
        })
    }
}

impl Model for ReferenceFmu {
    /// The time: the parameters are fixed once initialized, the signal a function of it.
    type Snapshot = f64;

    fn info() -> ModelInfo {
        ModelInfo {
            model_name: "HydroBench.Reference",
            model_identifier: "reference",
            description: "Reference signals of the thesis (moves, steps, sine, sweep, ramp): position reference with its first three derivatives and a pressure reference",
            default_experiment: DefaultExperiment { start_time: 0.0, stop_time: 2.6, tolerance: None, step_size: Some(1e-3) },
            equations: &[
                "section 5.5: 7th-order moves s = 35 tau^4 - 84 tau^5 + 70 tau^6 - 20 tau^7",
                "Fig. 4.8 steps; Figs. 4.9-4.14 sines; a logarithmic sweep and a ramp",
            ],
            parameters: None,
        }
    }

    fn variables() -> Vec<VarDef<Self>> {
        let mut v = vec![
            real_output("y_ref", "Position reference", "m", |m: &Self| m.out[0]),
            real_output(
                "dy_ref",
                "Velocity of the position reference",
                "m/s",
                |m: &Self| m.out[1],
            ),
            real_output(
                "d2y_ref",
                "Acceleration of the position reference",
                "m/s2",
                |m: &Self| m.out[2],
            ),
            real_output(
                "d3y_ref",
                "Jerk of the position reference",
                "m/s3",
                |m: &Self| m.out[3],
            ),
            real_output(
                "P_ref",
                "Pressure reference (the parameter `pressure`)",
                "Pa",
                |m: &Self| m.values[PRESSURE],
            ),
            enum_parameter(
                "signal",
                "Reference signal",
                &SIGNALS,
                1,
                |m: &Self| m.kind,
                |m, k| m.kind = k,
            ),
        ];
        for (k, (name, description, unit, start, min, max)) in PARAMETERS.into_iter().enumerate() {
            v.push(real_parameter(
                name,
                description,
                unit,
                start,
                min,
                max,
                move |m: &Self| m.values[k],
                move |m: &mut Self, x| m.values[k] = x,
            ));
        }
        v
    }

    fn instantiate(_resources: Option<&Path>) -> Result<Self, String> {
        Ok(ReferenceFmu {
            kind: 1,
            values: PARAMETERS.iter().map(|s| s.3).collect(),
            t: 0.0,
            signal: None,
            out: [0.0; 4],
        })
    }

    fn initialize(&mut self, start_time: f64) -> Result<(), String> {
        self.signal = Some(self.signal()?);
        self.t = start_time;
        self.refresh()
    }

    fn refresh(&mut self) -> Result<(), String> {
        let signal = self.signal.as_ref().ok_or("not initialized")?;
        let out = signal.at(self.t);
        if !out.iter().all(|x| x.is_finite()) {
            return Err(format!("the reference is not finite at t = {} s", self.t));
        }
        self.out = out;
        Ok(())
    }

    fn do_step(&mut self, h: f64) -> Result<(), String> {
        self.t += h;
        self.refresh()
    }

    fn time(&self) -> f64 {
        self.t
    }

    fn snapshot(&self) -> f64 {
        self.t
    }

    fn restore(&mut self, t: f64) -> Result<(), String> {
        self.t = t;
        if self.signal.is_some() {
            self.refresh()?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(kind: i32, t: f64) -> [f64; 4] {
        let mut m = ReferenceFmu::instantiate(None).unwrap();
        m.kind = kind;
        m.initialize(t).unwrap();
        m.out
    }

    /// Each derivative output is the finite difference of the one before it.
    #[test]
    fn derivatives_are_the_finite_differences_of_the_outputs() {
        let h = 1e-6;
        for (kind, t) in [(1, 1.1), (3, 0.013), (4, 3.7), (5, 1.5)] {
            let (lo, hi, mid) = (at(kind, t - h), at(kind, t + h), at(kind, t));
            for d in 0..3 {
                let fd = (hi[d] - lo[d]) / (2.0 * h);
                let scale = mid[d + 1].abs().max(1e-3);
                assert!(
                    (fd - mid[d + 1]).abs() < 1e-4 * scale,
                    "{kind} {d}: {fd} vs {}",
                    mid[d + 1]
                );
            }
        }
    }

    #[test]
    fn signals_reach_their_thesis_levels() {
        assert_eq!(at(1, 0.5)[0], THESIS_LOW);
        assert_eq!(at(1, 1.5)[0], THESIS_HIGH);
        assert_eq!(at(1, 2.5)[0], THESIS_LOW);
        assert_eq!(at(2, 0.2)[0], STEP_AMPLITUDE);
        assert_eq!(at(2, 0.4)[0], -STEP_AMPLITUDE);
        assert_eq!(at(5, 3.0)[0], THESIS_HIGH);
        // the sweep's frequency at mid-duration is the geometric mean: 10 Hz
        // (y = A sin(phi), dy = A cos(phi) phi': phi' = |dy| / sqrt(A^2 - y^2))
        let [y, dy, _, _] = at(4, 5.0);
        let w = dy.abs() / (SINE_AMPLITUDE.powi(2) - y * y).sqrt();
        assert!((w / (2.0 * std::f64::consts::PI) - 10.0).abs() < 0.1, "{w}");
    }
}
