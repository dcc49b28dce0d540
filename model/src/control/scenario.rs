//! The thesis's closed-loop experiments as named, reproducible scenarios: what the bench
//! is asked to do (reference, pressure reference, load), by which law, and over which
//! time windows its errors are judged. `hbench simulate`, `hbench tables` and the sweep
//! studies all run these, so a figure in the docs and a point of a study mean the same
//! experiment.

use serde::Serialize;

use super::backstepping::{Gains, LAMBDA_THESIS, P_REF_THESIS};
use super::config::{ControllerParams, LawKind};
use super::law::Reference;
use super::model_free::{KP_HIGH, KP_LOW};
use super::sampled::{StateSource, DAO2_GAINS};
pub use super::signal::Signal;
use super::trajectory::Trajectory;
use super::{run_sampled, Sample, Timing};
use crate::{Effect, Mode, Params, Simulation};

/// Proportional gain of the section 4.4 step and sine tests (V/m).
pub const KP_SECTION_4_4: f64 = 1169.0;
/// Proportional gain Table 5.1 compares the backstepping laws with (V/m).
pub const KP_TABLE_5_1: f64 = 5200.0;
/// The lowered DAO2 gains of the chapter-7 robustness test (section 7.4, Figs. 7.10-7.11).
pub const DAO2_GAINS_LOW: [f64; 2] = [60.0, 25.0];
/// Moving mass of the chapter-7 simulations (section 7.2), kg.
pub const CHAPTER_7_MASS: f64 = 6.9;
/// Payloads of the chapter-7 robustness tests (Tables 7.1-7.4), kg.
pub const PAYLOADS: [f64; 4] = [0.0, 20.0, 50.0, 100.0];
/// Amplitude of the section 4.4 sine tests (Figs. 4.9-4.14), m.
pub const SINE_AMPLITUDE: f64 = 3.4e-3;
/// Sine frequency when none is given (Hz): inside the 1-100+ Hz range of Figs. 4.9-4.14,
/// where the loop's phase lag is already large but far from the manifold resonance.
pub const SINE_FREQUENCY: f64 = 50.0;
/// Position of the +-10 mm steps of Fig. 4.8, m.
pub const STEP_AMPLITUDE: f64 = 10e-3;

/// Moves, holds and times of one thesis cycle (section 5.5): two moves of 0.2 s at 1 s
/// and 2 s; errors are judged on the moves and on the holds once the transient is over.
const MOVES_END: f64 = 2.6;
/// Steps of Fig. 4.8: -10 mm to +10 mm at 0.05 s and back at 0.35 s; each settles within
/// 0.1 s at Kp = 1169 V/m (95 % times 0.03-0.06 s).
pub const STEP_TIMES: [f64; 2] = [0.05, 0.35];
const STEPS_END: f64 = 0.65;
/// Sine runs: 4 periods (at least 0.1 s) of settling, then 10 periods judged.
const SINE_SETTLE_PERIODS: f64 = 4.0;
const SINE_JUDGED_PERIODS: f64 = 10.0;

/// Which part of a run a window judges.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum WindowKind {
    /// While the reference moves: the tables' max and STD of the transient error.
    Transient,
    /// On a hold after the transient: the tables' static mean and STD.
    Static,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Window {
    pub kind: WindowKind,
    pub start: f64,
    pub end: f64,
}

/// One closed-loop experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// What the run is called in files and legends.
    pub label: String,
    pub params: Params,
    pub controller: ControllerParams,
    pub signal: Signal,
    /// Pressure reference of the backstepping laws (P0 or P1d), Pa.
    pub p_ref: f64,
    pub duration: f64,
    pub windows: Vec<Window>,
}

/// Figures of merit of one run, SI units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Metrics {
    /// max |y - y_d| over the transient windows (m).
    pub transient_max: f64,
    pub transient_rms: f64,
    /// Standard deviation of y - y_d over the transient windows (m), as the tables give.
    pub transient_std: f64,
    /// Mean and standard deviation of y - y_d over the static windows (m).
    pub static_mean: f64,
    pub static_std: f64,
    /// Highest chamber pressure (Pa).
    pub peak_pressure: f64,
    /// Energy drawn from the supply, integral of P_supply Q_supply dt (J).
    pub supply_energy: f64,
    /// max |pressure tracked - P_ref| after the first second, for the laws that track a
    /// pressure (P-Y: P1; Y-lambda: (1 - lambda) P1 + lambda P2), in Pa.
    pub pressure_error_max: Option<f64>,
    /// Largest |u| (V) and the share of samples at the +-10 V limit.
    pub command_max: f64,
    pub saturated_fraction: f64,
}

/// How a run behaved, judged from its metrics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// Follows the moves and holds still on the plateaus.
    Stable,
    /// Follows the moves but limit-cycles on the plateaus.
    Oscillating,
    /// Loses the reference (errors of a quarter of the move or more, or a static offset
    /// of a millimetre).
    Lost,
}

/// Static STD above which a noiseless simulation is limit-cycling (m): a settled loop
/// holds within a few um here, and the bench, with its sensor noise, showed 32-41 um
/// (Tables 5.1, 6.1).
pub const OSCILLATION_STD: f64 = 30e-6;
/// Transient error (m) at which a run has lost the +-10 mm moves: a quarter of a move.
pub const LOST_TRANSIENT: f64 = 5e-3;
/// Static offset (m) at which a run has lost its position.
pub const LOST_STATIC: f64 = 1e-3;

impl Metrics {
    pub fn verdict(&self) -> Verdict {
        if self.transient_max > LOST_TRANSIENT || self.static_mean.abs() > LOST_STATIC {
            Verdict::Lost
        } else if self.static_std > OSCILLATION_STD {
            Verdict::Oscillating
        } else {
            Verdict::Stable
        }
    }
}

/// A run: the scenario's trace and its metrics.
#[derive(Debug, Clone)]
pub struct Run {
    pub trace: Vec<Sample>,
    pub metrics: Metrics,
}

/// Laws with the thesis's gains under their usual names, for the command line.
pub fn thesis_controller(law: LawKind, high_gains: bool) -> ControllerParams {
    let g = match (law, high_gains) {
        (_, false) => Gains::LOW,
        (LawKind::PY, true) => Gains::HIGH_P_Y,
        (_, true) => Gains::HIGH_Y_LAMBDA,
    };
    ControllerParams {
        law,
        kp: if law == LawKind::Proportional && high_gains {
            KP_TABLE_5_1
        } else {
            KP_SECTION_4_4
        },
        c: [g.c1, g.c2, g.c3, g.c4],
        lambda: LAMBDA_THESIS,
        kp_model_free: if high_gains { KP_HIGH } else { KP_LOW },
        source: StateSource::Dao2,
        dao2: DAO2_GAINS,
        ..ControllerParams::default()
    }
}

impl Scenario {
    /// The chapter 5-7 cycle: two up-and-down 7th-order moves between -10 and +10 mm.
    pub fn moves(params: Params, controller: ControllerParams) -> Scenario {
        Scenario {
            label: "moves".into(),
            params,
            controller,
            signal: Signal::Moves(Trajectory::thesis()),
            p_ref: P_REF_THESIS,
            duration: MOVES_END,
            windows: vec![
                window(WindowKind::Transient, 1.0, 1.3),
                window(WindowKind::Static, 1.6, 2.0),
                window(WindowKind::Transient, 2.0, 2.3),
                window(WindowKind::Static, 2.4, MOVES_END),
            ],
        }
    }

    /// Fig. 4.8: +-10 mm steps under proportional control.
    pub fn steps(params: Params, controller: ControllerParams) -> Scenario {
        let [t1, t2] = STEP_TIMES;
        Scenario {
            label: "steps".into(),
            params,
            controller,
            signal: Signal::Steps {
                low: -STEP_AMPLITUDE,
                high: STEP_AMPLITUDE,
                times: STEP_TIMES.to_vec(),
            },
            p_ref: P_REF_THESIS,
            duration: STEPS_END,
            windows: vec![
                window(WindowKind::Transient, t1, t1 + 0.1),
                window(WindowKind::Static, t1 + 0.2, t2),
                window(WindowKind::Transient, t2, t2 + 0.1),
                window(WindowKind::Static, t2 + 0.2, STEPS_END),
            ],
        }
    }

    /// Figs. 4.9-4.14: a 3.4 mm sine about mid stroke.
    pub fn sine(params: Params, controller: ControllerParams, frequency: f64) -> Scenario {
        let settle = (SINE_SETTLE_PERIODS / frequency).max(0.1);
        let end = settle + SINE_JUDGED_PERIODS / frequency;
        Scenario {
            label: format!("sine_{frequency}Hz"),
            params,
            controller,
            signal: Signal::Sine {
                amplitude: SINE_AMPLITUDE,
                frequency,
            },
            p_ref: P_REF_THESIS,
            duration: end,
            windows: vec![window(WindowKind::Transient, settle, end)],
        }
    }

    pub fn reference(&self, t: f64) -> Reference {
        Reference {
            y: self.signal.at(t),
            p: [self.p_ref, 0.0],
        }
    }

    /// Simulate the scenario on the bench; the law believes the nominal mass (payloads
    /// are unknown to it, as in chapter 7).
    pub fn run(&self) -> Result<Run, String> {
        let mut p = self.params.clone();
        p.initial_position = self.signal.at(0.0)[0];
        let mut ctrl = self.controller.controller(&p);
        let mut sim = Simulation::new(&p).map_err(|e| e.to_string())?;
        let timing = Timing {
            period: self.controller.period,
            substeps: 1,
            computation_delay: self.controller.computation_delay,
        };
        let reference = |t: f64| self.reference(t);
        let trace = run_sampled(&mut sim, &mut ctrl, &reference, self.duration, &timing)
            .map_err(|e| format!("{}: {e}", self.label))?;
        let metrics = self.metrics(&trace);
        Ok(Run { trace, metrics })
    }

    /// The pressure the law tracks, for laws that track one.
    fn tracked_pressure(&self, s: &Sample) -> Option<f64> {
        let l = self.controller.lambda;
        match self.controller.law {
            LawKind::PY => Some(s.out.p1),
            // (5.15) (1 - lambda) P1 + lambda P2 = P0
            LawKind::YLambda => Some((1.0 - l) * s.out.p1 + l * s.out.p2),
            _ => None,
        }
    }

    pub fn metrics(&self, trace: &[Sample]) -> Metrics {
        let inside = |kind: WindowKind| -> Vec<f64> {
            trace
                .iter()
                .filter(|s| self.windows.iter().any(|w| w.contains(kind, s.t)))
                .map(|s| s.out.y - s.reference)
                .collect()
        };
        let (tr, st) = (inside(WindowKind::Transient), inside(WindowKind::Static));
        let (_, transient_std) = mean_std(&tr);
        let (static_mean, static_std) = mean_std(&st);
        let rms = |v: &[f64]| (v.iter().map(|e| e * e).sum::<f64>() / v.len().max(1) as f64).sqrt();
        let mut energy = 0.0;
        let mut t_prev = trace.first().map_or(0.0, |s| s.t);
        for s in trace {
            energy += self.params.supply_pressure * s.out.q_supply * (s.t - t_prev);
            t_prev = s.t;
        }
        let settled = |s: &&Sample| s.t >= PRESSURE_SETTLE.min(0.5 * self.duration);
        let pressure_error_max = trace
            .iter()
            .filter(settled)
            .filter_map(|s| self.tracked_pressure(s).map(|p| (p - self.p_ref).abs()))
            .reduce(f64::max);
        let commands = || trace.iter().flat_map(|s| [s.inputs.u1, s.inputs.u2]);
        let n_commands = 2 * trace.len().max(1);
        Metrics {
            transient_max: tr.iter().fold(0.0, |a, e| a.max(e.abs())),
            transient_rms: rms(&tr),
            transient_std,
            static_mean,
            static_std,
            peak_pressure: trace
                .iter()
                .map(|s| s.out.p1.max(s.out.p2))
                .fold(0.0, f64::max),
            supply_energy: energy,
            pressure_error_max,
            command_max: commands().fold(0.0, |a, u| a.max(u.abs())),
            saturated_fraction: commands()
                .filter(|u| u.abs() >= 0.999 * super::COMMAND_LIMIT)
                .count() as f64
                / n_commands as f64,
        }
    }
}

/// Time after which a pressure-tracking law's pressure has left its initial transient
/// (the chambers start at the rest pressures, not at P_ref): the first move starts at 1 s.
const PRESSURE_SETTLE: f64 = 0.5;

/// s, tolerance on a window's edges: sample times are sums of periods whose round-off
/// (1e-16 s) may put a sample meant to sit on an edge on either side; 1 ns is far below
/// any sampling period and far above that round-off. tools/sweep/evaluate.py uses the
/// same, so a study and `hbench simulate` count the same samples.
pub const WINDOW_EDGE: f64 = 1e-9;

impl Window {
    /// Whether a sample at `t` belongs to this window of kind `kind`: half-open
    /// [start, end), so that a window's end is the next one's start.
    pub fn contains(&self, kind: WindowKind, t: f64) -> bool {
        self.kind == kind && t >= self.start - WINDOW_EDGE && t < self.end - WINDOW_EDGE
    }
}

fn window(kind: WindowKind, start: f64, end: f64) -> Window {
    Window { kind, start, end }
}

fn mean_std(v: &[f64]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n;
    (mean, var.sqrt())
}

/// A named experiment of the thesis: one or several runs compared in one figure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Catalogue {
    pub name: &'static str,
    pub description: &'static str,
}

/// The experiments `hbench simulate --scenario` knows.
pub const CATALOGUE: [Catalogue; 8] = [
    Catalogue {
        name: "steps",
        description:
            "+-10 mm steps under proportional control, Kp = 1169 V/m (section 4.4, Fig. 4.8)",
    },
    Catalogue {
        name: "sine",
        description:
            "3.4 mm closed-loop sine under proportional control, Kp = 1169 V/m (Figs. 4.9-4.14)",
    },
    Catalogue {
        name: "moves",
        description: "the chapter 5-7 cycle of 7th-order +-10 mm moves under one law",
    },
    Catalogue {
        name: "payloads",
        description:
            "the moves with payloads +0, 20, 50, 100 kg unknown to the law (Tables 7.1-7.4)",
    },
    Catalogue {
        name: "gains",
        description: "the moves with the low and the high gains of the law (Table 5.1, Table 6.1)",
    },
    Catalogue {
        name: "dao2",
        description:
            "the moves with the DAO2 gains 200/80 and 60/25 1/s (section 7.4, Figs. 7.10-7.11)",
    },
    Catalogue {
        name: "laws",
        description: "the moves under every law at its thesis gains (Tables 5.1 and 6.1)",
    },
    Catalogue {
        name: "modes",
        description:
            "the moves under one law in working modes 1, 2 and 3 (stability in every mode)",
    },
];

/// Choices a user may change from the command line; `None` keeps the scenario's own.
#[derive(Debug, Clone, Default)]
pub struct Overrides {
    pub mode: Option<Mode>,
    pub law: Option<LawKind>,
    pub high_gains: Option<bool>,
    pub payload: Option<f64>,
    pub dao2: Option<[f64; 2]>,
    pub source: Option<StateSource>,
    pub frequency: Option<f64>,
    pub computation_delay: Option<f64>,
    /// Sampling period of the law (s); the thesis's board runs at 1 kHz.
    pub period: Option<f64>,
}

/// The runs of a named experiment on `base` (the bench parameters; the thesis bench by
/// default), with the user's overrides.
pub fn build(name: &str, base: &Params, o: &Overrides) -> Result<Vec<Scenario>, String> {
    let mut params = base.clone();
    if let Some(mode) = o.mode {
        params.mode = mode;
    }
    let default_law = match name {
        "steps" | "sine" => LawKind::Proportional,
        _ => LawKind::PY,
    };
    let law = o.law.unwrap_or(default_law);
    let controller = |law: LawKind, high: bool| {
        let mut c = thesis_controller(law, high);
        if let Some(d) = o.dao2 {
            c.dao2 = d;
        }
        if let Some(s) = o.source {
            c.source = s;
        }
        if let Some(d) = o.computation_delay {
            c.computation_delay = d;
        }
        if let Some(h) = o.period {
            c.period = h;
        }
        c
    };
    // the steps and sines of section 4.4 use 1169 V/m whatever "high gains" says
    let high = o.high_gains.unwrap_or(!matches!(name, "steps" | "sine"));
    let with_payload = |mut p: Params, kg: f64| {
        p.actuator.payload_mass = kg;
        p.effects.set(Effect::Payload, kg > 0.0);
        p
    };
    if let Some(kg) = o.payload {
        params = with_payload(params, kg);
    }
    let named = |mut s: Scenario, label: String| {
        s.label = label;
        s
    };
    let runs = match name {
        "steps" => vec![Scenario::steps(params, controller(law, high))],
        "sine" => vec![Scenario::sine(
            params,
            controller(law, high),
            o.frequency.unwrap_or(SINE_FREQUENCY),
        )],
        "moves" => vec![named(
            Scenario::moves(params, controller(law, high)),
            format!("moves_{}", law_name(law)),
        )],
        "payloads" => {
            params.actuator.mass = CHAPTER_7_MASS;
            PAYLOADS
                .iter()
                .map(|&kg| {
                    named(
                        Scenario::moves(with_payload(params.clone(), kg), controller(law, high)),
                        format!("{}_payload_{kg}kg", law_name(law)),
                    )
                })
                .collect()
        }
        "gains" => [false, true]
            .iter()
            .map(|&h| {
                named(
                    Scenario::moves(params.clone(), controller(law, h)),
                    format!("{}_{}_gains", law_name(law), if h { "high" } else { "low" }),
                )
            })
            .collect(),
        "dao2" => [DAO2_GAINS, DAO2_GAINS_LOW]
            .iter()
            .map(|&g| {
                let mut c = controller(law, high);
                c.dao2 = g;
                named(
                    Scenario::moves(params.clone(), c),
                    format!("{}_dao2_{}_{}", law_name(law), g[0], g[1]),
                )
            })
            .collect(),
        "laws" => LawKind::ALL
            .iter()
            .map(|&l| {
                named(
                    Scenario::moves(params.clone(), controller(l, high)),
                    format!("moves_{}", law_name(l)),
                )
            })
            .collect(),
        "modes" => [Mode::FourWaySingle, Mode::FourWayParallel, Mode::ThreeWay]
            .iter()
            .map(|&m| {
                let mut p = params.clone();
                p.mode = m;
                named(
                    Scenario::moves(p, controller(law, high)),
                    format!("{}_mode_{}", law_name(law), m.number()),
                )
            })
            .collect(),
        _ => {
            let known: Vec<_> = CATALOGUE.iter().map(|c| c.name).collect();
            return Err(format!(
                "unknown scenario '{name}'; known: {}",
                known.join(", ")
            ));
        }
    };
    Ok(runs)
}

/// The law's name in scenarios, on the command line and in the FMUs' enumeration.
pub const fn law_name(law: LawKind) -> &'static str {
    match law {
        LawKind::Proportional => "proportional",
        LawKind::YLambda => "y_lambda",
        LawKind::PY => "p_y",
        LawKind::ModelFree => "model_free",
        LawKind::RestrictedModel => "restricted_model",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sine_derivatives_are_the_analytic_ones() {
        let s = Signal::Sine {
            amplitude: 1e-3,
            frequency: 10.0,
        };
        let h = 1e-6;
        for t in [0.01, 0.033, 0.07] {
            let (a, b) = (s.at(t - h), s.at(t + h));
            for k in 0..3 {
                let fd = (b[k] - a[k]) / (2.0 * h);
                assert!((fd - s.at(t)[k + 1]).abs() <= 1e-6 * s.at(t)[k + 1].abs().max(1e-3));
            }
        }
    }

    #[test]
    fn every_catalogued_experiment_builds_and_unknown_names_are_refused() {
        let base = Params::thesis_bench(Mode::ThreeWay);
        for c in CATALOGUE {
            let runs = build(c.name, &base, &Overrides::default()).unwrap();
            assert!(!runs.is_empty(), "{}", c.name);
            for r in &runs {
                assert!(r.windows.iter().all(|w| w.end <= r.duration + 1e-12));
            }
        }
        let e = build("nope", &base, &Overrides::default()).unwrap_err();
        assert!(e.contains("steps") && e.contains("modes"), "{e}");
    }

    #[test]
    fn payload_runs_carry_the_payload_the_law_does_not_know() {
        let runs = build("payloads", &Params::default(), &Overrides::default()).unwrap();
        let kg: Vec<f64> = runs
            .iter()
            .map(|r| r.params.actuator.payload_mass)
            .collect();
        assert_eq!(kg, PAYLOADS);
        assert!(!runs[0].params.has(Effect::Payload) && runs[3].params.has(Effect::Payload));
        assert!(runs
            .iter()
            .all(|r| r.params.actuator.mass == CHAPTER_7_MASS));
    }
}
