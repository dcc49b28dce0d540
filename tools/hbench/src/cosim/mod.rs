//! `hbench cosim`: the bench co-simulated from its component FMUs (two servovalves,
//! manifold, actuator) as `bench.ssp` wires them, against the monolithic `bench.fmu`.
//!
//! Both run the same experiment under the same sampled proportional controller (the
//! thesis's: 1 kHz, u1 = -u2 = Kp (y_ref - y), +-10 V, no delay), computed by this master
//! from the system output y, or for the system, with `--controller`, by controller.fmu
//! inside it (the package's closed-loop variants, stepped at 1 ms by the multi-rate
//! master); only the plant differs. The comparison is taken at the control instants
//! (every 1 ms), where both hold the same command.

pub mod master;
pub mod ssp;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use hbfmu::slave::Value;
use hbmodel::control::trajectory::{Trajectory, THESIS_HIGH, THESIS_LOW, THESIS_MOVE_DURATION};
use hbmodel::params::BAR;
use hbmodel::Mode;

use master::{Master, Order};
use ssp::systems::{MOVE_START, MOVE_STOP};
use ssp::{Component, Package, System, ACTUATOR, CONTROLLER, REFERENCE, SV1, SV2};
/// Controller sampling period (s), the thesis bench's.
pub const CONTROL_PERIOD: f64 = 1e-3;
/// Proportional gain of the thesis step tests (V/m).
pub const KP: f64 = 1169.0;
/// Servovalve command limit (V).
pub const U_MAX: f64 = 10.0;
/// Pressure error (Pa) beyond which a run that finished counts as diverged.
const DIVERGED_PRESSURE: f64 = 100.0 * BAR;
/// Communication steps of the sweep (s): all divide the control period.
pub const SWEEP_STEPS: [f64; 5] = [0.05e-3, 0.1e-3, 0.2e-3, 0.5e-3, 1e-3];

/// A closed-loop experiment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Experiment {
    /// The thesis's 7th-order move, -10 mm to +10 mm in 0.2 s, starting at 20 ms.
    Move,
    /// A 3.4 mm sine at 50 Hz around mid stroke (the mode-1 sweep's amplitude).
    Sine,
}

const SINE_AMPLITUDE: f64 = 3.4e-3;
const SINE_FREQUENCY: f64 = 50.0;

impl Experiment {
    pub fn name(self) -> &'static str {
        match self {
            Experiment::Move => "move",
            Experiment::Sine => "sine",
        }
    }
    /// Initial piston position (m).
    pub fn y0(self) -> f64 {
        match self {
            Experiment::Move => THESIS_LOW,
            Experiment::Sine => 0.0,
        }
    }
    /// The amplitude errors are measured against (m).
    pub fn amplitude(self) -> f64 {
        match self {
            Experiment::Move => THESIS_HIGH - THESIS_LOW,
            Experiment::Sine => SINE_AMPLITUDE,
        }
    }
    pub fn stop_time(self) -> f64 {
        match self {
            // the move and 80 ms of settling
            Experiment::Move => MOVE_STOP,
            // five periods
            Experiment::Sine => 0.1,
        }
    }
    /// Reference position at the control instants 0, T, 2T, ... up to the stop time.
    pub fn reference(self) -> Vec<(f64, f64)> {
        let n = (self.stop_time() / CONTROL_PERIOD).round() as usize;
        let tr = Trajectory::new(&[(MOVE_START, THESIS_LOW, THESIS_HIGH, THESIS_MOVE_DURATION)])
            .expect("one move is a valid trajectory");
        (0..=n)
            .map(|k| {
                let t = k as f64 * CONTROL_PERIOD;
                let y = match self {
                    Experiment::Move => tr.at(t)[0],
                    Experiment::Sine => {
                        SINE_AMPLITUDE * (2.0 * std::f64::consts::PI * SINE_FREQUENCY * t).sin()
                    }
                };
                (t, y)
            })
            .collect()
    }
}

/// Samples at the control instants: t, y_ref, y, P1, P2.
type Trace = Vec<[f64; 5]>;

/// Where the loop is closed: the valve commands, the position and the chamber pressures,
/// as `Element.variable`, in bench.fmu alone or in the system of components.
fn io(m: &Master) -> [String; 5] {
    let ends = if m.has(MONOLITHIC) {
        ["u1", "u2", "y", "P1", "P2"].map(|v| (MONOLITHIC, v))
    } else {
        [
            (SV1, "u"),
            (SV2, "u"),
            (ACTUATOR, "y"),
            (ACTUATOR, "P1"),
            (ACTUATOR, "P2"),
        ]
    };
    ends.map(|(e, v)| format!("{e}.{v}"))
}

/// Close the loop around bench.fmu or a system of components (see [`io`]).
fn closed_loop(
    m: &mut Master,
    exp: Experiment,
    mode: Mode,
    h: f64,
    order: Order,
) -> Result<Trace, String> {
    let sub = (CONTROL_PERIOD / h).round().max(1.0) as usize;
    let h = CONTROL_PERIOD / sub as f64;
    let mut trace = Vec::new();
    let [u1_in, u2_in, y_out, p1_out, p2_out] = io(m);
    for (t, y_ref) in exp.reference() {
        let y = m.output(&y_out)?;
        let (p1, p2) = (m.output(&p1_out)?, m.output(&p2_out)?);
        if ![y, p1, p2].iter().all(|x| x.is_finite()) || y.abs() > 0.2 {
            return Err(format!("diverged at t = {t:.4} s (y = {y:e} m)"));
        }
        trace.push([t, y_ref, y, p1, p2]);
        if t >= exp.stop_time() - 1e-9 {
            break;
        }
        // with controller.fmu in the system, reference.fmu feeds it: nothing to set
        if !m.has(CONTROLLER) {
            let u = (KP * (y_ref - y)).clamp(-U_MAX, U_MAX);
            m.set_input(&u1_in, u)?;
            // mode 1 drives the actuator with SV1 alone; SV2 stays connected, at null
            let u2 = if mode == Mode::FourWaySingle { 0.0 } else { -u };
            m.set_input(&u2_in, u2)?;
        }
        for _ in 0..sub {
            m.step(h, order)
                .map_err(|e| format!("at t = {:.5} s: {e}", m.t))?;
        }
    }
    Ok(trace)
}

/// Instance name of bench.fmu in the monolithic reference.
const MONOLITHIC: &str = "bench";

/// A package holding `bench.fmu` alone.
fn monolithic(bench_fmu: &Path) -> Result<Package, String> {
    let bytes = std::fs::read(bench_fmu)
        .map_err(|e| format!("cannot read {}: {e}", bench_fmu.display()))?;
    let system = System {
        name: MONOLITHIC.into(),
        inputs: vec![],
        outputs: vec![],
        components: vec![Component {
            name: MONOLITHIC.into(),
            source: "bench.fmu".into(),
            inputs: vec![],
            outputs: vec![],
            parameters: vec![],
        }],
        connections: vec![],
    };
    Ok(Package {
        system,
        fmus: [("bench.fmu".to_string(), bytes)].into(),
    })
}

/// The mode and initial position of every component that has them, and the signal of
/// reference.fmu where the system has one (the package binds the move; see
/// `ssp::systems::move_reference`).
fn overrides(exp: Experiment, mode: Mode) -> Vec<(&'static str, &'static str, Value)> {
    let mut o = vec![
        ("*", "mode", Value::Integer(mode.number() as i32)),
        ("*", "y0", Value::Real(exp.y0())),
    ];
    if exp == Experiment::Sine {
        o.extend([
            (REFERENCE, "signal", Value::Integer(3)),
            (REFERENCE, "sine.amplitude", Value::Real(SINE_AMPLITUDE)),
            (REFERENCE, "sine.frequency", Value::Real(SINE_FREQUENCY)),
        ]);
    }
    o
}

/// The monolithic reference: bench.fmu at the control period.
pub fn run_bench(bench: &Package, exp: Experiment, mode: Mode) -> Result<Trace, String> {
    let mut m = Master::new(bench, &overrides(exp, mode))?;
    closed_loop(&mut m, exp, mode, CONTROL_PERIOD, Order::Jacobi)
}

/// The system of components at communication step `h`.
pub fn run_cosim(
    pkg: &Package,
    exp: Experiment,
    mode: Mode,
    h: f64,
    order: Order,
) -> Result<Trace, String> {
    let mut m = Master::new(pkg, &overrides(exp, mode))?;
    if m.has(CONTROLLER) {
        m.sample_every(CONTROLLER, CONTROL_PERIOD)?;
    }
    closed_loop(&mut m, exp, mode, h, order)
}

/// Largest position error (fraction of the amplitude) and chamber-pressure error (Pa).
pub fn errors(exp: Experiment, a: &Trace, b: &Trace) -> (f64, f64) {
    let mut ey: f64 = 0.0;
    let mut ep: f64 = 0.0;
    for (x, y) in a.iter().zip(b) {
        ey = ey.max((x[2] - y[2]).abs());
        ep = ep.max((x[3] - y[3]).abs()).max((x[4] - y[4]).abs());
    }
    (ey / exp.amplitude(), ep)
}

/// One co-simulation compared with bench.fmu.
pub struct Outcome {
    pub experiment: Experiment,
    pub mode: Mode,
    pub order: Order,
    pub step: f64,
    /// The errors, or why the run stopped.
    pub result: Result<(f64, f64), String>,
    pub seconds: f64,
    pub trace: Option<Trace>,
}

#[derive(clap::Args)]
pub struct CosimArgs {
    /// The SSP package of the component FMUs (written by `hbench fmu` beside them)
    #[arg(long, default_value = "out/fmu/bench.ssp")]
    system: PathBuf,
    /// The monolithic bench.fmu to compare with (default: next to the package)
    #[arg(long)]
    bench: Option<PathBuf>,
    /// Working modes (1: SV1 4-way, 2: both 4-way in parallel, 3: each valve 3-way)
    #[arg(long, value_delimiter = ',', default_values_t = [1u8, 2, 3])]
    modes: Vec<u8>,
    /// Coupling orders
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [Order::Jacobi, Order::GaussSeidel])]
    order: Vec<Order>,
    /// Communication steps (s); each must divide the 1 ms control period
    #[arg(long, value_delimiter = ',', default_values_t = [1e-4])]
    steps: Vec<f64>,
    /// Run every step of the study: 0.05, 0.1, 0.2, 0.5 and 1 ms (overrides --steps)
    #[arg(long)]
    sweep: bool,
    /// Experiments
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [Experiment::Move, Experiment::Sine])]
    experiments: Vec<Experiment>,
    /// Directory for cosim_errors.json, cosim_traces.csv and reference_<experiment>.csv
    #[arg(long, default_value = "out/cosim")]
    out: PathBuf,
    /// Close the loop with controller.fmu inside the system (the package's ClosedLoop
    /// variants, controller sampled at 1 ms) instead of the master's own proportional law
    #[arg(long)]
    controller: bool,
    /// Also write the error-vs-step plot (SVG) of the runs to this file
    #[arg(long)]
    plot: Option<PathBuf>,
}

pub fn main(args: CosimArgs) -> Result<(), String> {
    let package = |mode: Mode| -> Result<Package, String> {
        let file = std::fs::File::open(&args.system)
            .map_err(|e| format!("cannot open {}: {e}", args.system.display()))?;
        if args.controller {
            ssp::open_variant(file, ssp::closed_loop_ssd(mode))
        } else {
            ssp::open(file)
        }
    };
    let bench_path = args.bench.clone().unwrap_or_else(|| {
        args.system
            .parent()
            .unwrap_or(Path::new("."))
            .join("bench.fmu")
    });
    let bench = monolithic(&bench_path)?;
    let steps = if args.sweep {
        SWEEP_STEPS.to_vec()
    } else {
        args.steps.clone()
    };
    for &h in &steps {
        let n = CONTROL_PERIOD / h;
        if !(h > 0.0 && (n - n.round()).abs() < 1e-9) {
            return Err(format!(
                "communication step {h} s does not divide the 1 ms control period"
            ));
        }
    }
    let modes = args
        .modes
        .iter()
        .map(|&k| Mode::try_from(k).map_err(|_| format!("no mode {k}: 1, 2 or 3")))
        .collect::<Result<Vec<_>, _>>()?;
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    let mut outcomes = Vec::new();
    let mut references = Vec::new();
    for &exp in &args.experiments {
        write_reference(&args.out, exp)?;
        for &mode in &modes {
            let pkg = package(mode)?;
            let t0 = Instant::now();
            let reference = run_bench(&bench, exp, mode)?;
            eprintln!(
                "bench.fmu {} mode {}: {:.2} s",
                exp.name(),
                mode.number(),
                t0.elapsed().as_secs_f64()
            );
            for &order in &args.order {
                for &h in &steps {
                    let t0 = Instant::now();
                    let run = run_cosim(&pkg, exp, mode, h, order);
                    let seconds = t0.elapsed().as_secs_f64();
                    let result = run
                        .as_ref()
                        .map(|tr| errors(exp, tr, &reference))
                        .map_err(|e| e.clone())
                        .and_then(|(ey, ep)| {
                            // bounded only by the valves' saturation: no longer a solution
                            if ey > 1.0 || ep > DIVERGED_PRESSURE {
                                Err(format!(
                                    "diverged: {:.0} % / {:.0} bar",
                                    100.0 * ey,
                                    ep / BAR
                                ))
                            } else {
                                Ok((ey, ep))
                            }
                        });
                    let o = Outcome {
                        experiment: exp,
                        mode,
                        order,
                        step: h,
                        result,
                        seconds,
                        trace: run.ok(),
                    };
                    eprintln!("{}", summary_line(&o));
                    outcomes.push(o);
                }
            }
            references.push((exp, mode, reference));
        }
    }
    std::fs::write(
        args.out.join("cosim_errors.json"),
        errors_json(&outcomes, args.controller),
    )
    .map_err(|e| e.to_string())?;
    if let Some(path) = &args.plot {
        plot_errors(path, &outcomes)?;
    }
    std::fs::write(
        args.out.join("cosim_traces.csv"),
        traces_csv(&outcomes, &references),
    )
    .map_err(|e| e.to_string())?;
    println!("{}", table(&outcomes));
    Ok(())
}

fn status(o: &Outcome) -> String {
    match &o.result {
        Ok((ey, ep)) => format!("{:.3} % / {:.2} bar", 100.0 * ey, ep / BAR),
        Err(e) => format!("unstable ({e})"),
    }
}

fn summary_line(o: &Outcome) -> String {
    format!(
        "{} mode {} {} h = {} ms: {} [{:.2} s]",
        o.experiment.name(),
        o.mode.number(),
        o.order.name(),
        o.step * 1e3,
        status(o),
        o.seconds
    )
}

fn write_reference(dir: &Path, exp: Experiment) -> Result<(), String> {
    let mut s = String::from("time,y_ref\n");
    for (t, y) in exp.reference() {
        let _ = writeln!(s, "{t:?},{y:?}");
    }
    let path = dir.join(format!("reference_{}.csv", exp.name()));
    std::fs::write(&path, s).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

fn errors_json(outcomes: &[Outcome], controller_fmu: bool) -> String {
    let runs: Vec<serde_json::Value> = outcomes
        .iter()
        .map(|o| {
            let (ey, ep, err) = match &o.result {
                Ok((ey, ep)) => (Some(100.0 * ey), Some(ep / BAR), None),
                Err(e) => (None, None, Some(e.clone())),
            };
            serde_json::json!({
                "experiment": o.experiment.name(),
                "mode": o.mode.number(),
                "order": o.order.name(),
                "step_ms": o.step * 1e3,
                "stable": o.result.is_ok(),
                "position_error_percent": ey,
                "pressure_error_bar": ep,
                "failure": err,
                "cpu_seconds": o.seconds,
            })
        })
        .collect();
    let doc = serde_json::json!({
        "control": {
            "law": "proportional", "Kp_V_per_m": KP, "period_s": CONTROL_PERIOD, "u_max_V": U_MAX,
            "computed_by": if controller_fmu { "controller.fmu in the system (bench.fmu: the master)" } else { "the master, for both" },
            "reads": "the true y (actuator.fmu's y, bench.fmu's y): no acquisition delay on either side",
        },
        "position_error": "largest |y - y_bench| at the control instants, percent of the amplitude (20 mm move, 3.4 mm sine)",
        "pressure_error": "largest |P_i - P_i,bench| of the two chambers at the control instants, bar",
        "runs": runs,
    });
    serde_json::to_string_pretty(&doc).unwrap_or_default()
}

fn traces_csv(outcomes: &[Outcome], references: &[(Experiment, Mode, Trace)]) -> String {
    let mut s = String::from("experiment,mode,order,step,time,y_ref,y,P1,P2\n");
    let mut row = |e: &str, m: u8, o: &str, h: f64, r: &[f64; 5]| {
        let _ = writeln!(
            s,
            "{e},{m},{o},{h:?},{:?},{:?},{:?},{:?},{:?}",
            r[0], r[1], r[2], r[3], r[4]
        );
    };
    for (e, m, tr) in references {
        for r in tr {
            row(e.name(), m.number(), "bench.fmu", 0.0, r);
        }
    }
    for o in outcomes {
        for r in o.trace.iter().flatten() {
            row(
                o.experiment.name(),
                o.mode.number(),
                o.order.name(),
                o.step,
                r,
            );
        }
    }
    s
}

/// Error against communication step, log-log: one row of panels per experiment
/// (position, pressure), one line per mode (colour) and order (Jacobi solid,
/// Gauss-Seidel dashed); an unstable run leaves its point out.
fn plot_errors(path: &Path, outcomes: &[Outcome]) -> Result<(), String> {
    use crate::plot::{LogLine, LogPanel};
    let mut experiments: Vec<Experiment> = outcomes.iter().map(|o| o.experiment).collect();
    experiments.dedup();
    let mut panels = Vec::new();
    for exp in experiments {
        for (what, unit) in [
            ("position", "% of the amplitude"),
            ("chamber pressure", "bar"),
        ] {
            let mut lines: Vec<LogLine> = Vec::new();
            for o in outcomes.iter().filter(|o| o.experiment == exp) {
                let label = format!("mode {} {}", o.mode.number(), o.order.name());
                let k = match lines.iter().position(|l| l.label == label) {
                    Some(k) => k,
                    None => {
                        lines.push(LogLine {
                            label,
                            points: vec![],
                            color: o.mode.number() as usize - 1,
                            dashed: o.order == Order::GaussSeidel,
                        });
                        lines.len() - 1
                    }
                };
                if let Ok((ey, ep)) = o.result {
                    let e = if unit == "bar" { ep / BAR } else { 100.0 * ey };
                    lines[k].points.push((o.step * 1e3, e));
                }
            }
            // issue 7's acceptance limit, across the steps studied
            let (limit, symbol) = if unit == "bar" {
                (5.0, "bar")
            } else {
                (2.0, "%")
            };
            let (h0, h1) = (
                SWEEP_STEPS[0] * 1e3,
                SWEEP_STEPS[SWEEP_STEPS.len() - 1] * 1e3,
            );
            lines.push(LogLine {
                label: format!("limit {limit} {symbol}"),
                points: vec![(h0, limit), (h1, limit)],
                color: 9,
                dashed: true,
            });
            panels.push(LogPanel {
                title: format!("{}: largest {what} error against bench.fmu", exp.name()),
                y_desc: format!("{what} error ({unit})"),
                lines,
            });
        }
    }
    crate::plot::log_log(
        path,
        "Co-simulated bench against bench.fmu (missing points: unstable)",
        "communication step (ms)",
        &panels,
        2,
    )
}

/// Markdown table: one row per experiment, mode and order; one column per step.
fn table(outcomes: &[Outcome]) -> String {
    let mut steps: Vec<f64> = outcomes.iter().map(|o| o.step).collect();
    steps.sort_by(f64::total_cmp);
    steps.dedup();
    let mut s = String::from("| experiment | mode | order |");
    for h in &steps {
        let _ = write!(s, " {} ms |", h * 1e3);
    }
    s += "\n|---|---|---|";
    s += &"---|".repeat(steps.len());
    let mut keys: Vec<(Experiment, u8, Order)> = Vec::new();
    for o in outcomes {
        let k = (o.experiment, o.mode.number(), o.order);
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    for (e, m, ord) in keys {
        let _ = write!(s, "\n| {} | {m} | {} |", e.name(), ord.name());
        for h in &steps {
            let cell = outcomes
                .iter()
                .find(|o| {
                    o.experiment == e && o.mode.number() == m && o.order == ord && o.step == *h
                })
                .map(|o| match &o.result {
                    Ok(_) => status(o),
                    Err(_) => "unstable".into(),
                })
                .unwrap_or_default();
            let _ = write!(s, " {cell} |");
        }
    }
    s + "\n\ncells: largest position error (% of the amplitude) / largest chamber-pressure error (bar) against bench.fmu"
}
