//! `hbench bench`: speed of the bench model in CPU time, the figures issue 13 asks for.
//!
//! The scenario of `hbench simulate --scenario moves`: mode 3, thesis parameters, the
//! thesis's 7th-order +-10 mm moves from -10 mm, proportional control Kp = 1169 V/m
//! sampled at 1 kHz. Three valve models (static and second-order reduced valves, the
//! two-stage valve), each integrated at rtol 1e-6 by diffsol's BDF, diffsol's ESDIRK34
//! and our integrator (`solver::adaptive`) back to back, all judged against one diffsol
//! ESDIRK34 run at rtol 1e-9 of the same case (a judge independent of our integrator);
//! the Python/scipy peer on the same scenario, judged against its own rtol 1e-9 run; and
//! the CPU cost of each 1 ms communication step in the fixed-step real-time mode.

pub(crate) mod cpu;
mod peer;

use hbmodel::control::trajectory::Trajectory;
use hbmodel::control::{run_loop, Controller, Proportional, Timing, SAMPLE_PERIOD};
use hbmodel::params::ValveModel;
use hbmodel::solver::{set_adaptive_method, Method, SolverStats};
use hbmodel::{Effect, Mode, Params, Simulation};
use serde_json::{json, Value};

/// The thesis's proportional gain (section 4.4), V/m.
const KP: f64 = 1169.0;
/// The tolerance the figures are for, and the one of the reference runs.
const RTOL: f64 = 1e-6;
const RTOL_REFERENCE: f64 = 1e-9;
/// The methods timed, in order: diffsol's BDF and ESDIRK34 (before), ours (after).
const METHODS: [Method; 3] = [Method::Bdf, Method::Esdirk34, Method::FilteredEsdirk34];

/// The valve models the bench is timed with.
#[derive(Clone, Copy)]
pub enum Valves {
    Static,
    SecondOrder,
    TwoStage,
}

impl Valves {
    fn name(self) -> &'static str {
        match self {
            Valves::Static => "static",
            Valves::SecondOrder => "second-order",
            Valves::TwoStage => "two-stage",
        }
    }

    fn params(self) -> Params {
        let mut p = Params::thesis_bench(Mode::ThreeWay);
        p.effects
            .set(Effect::ValveDynamics, matches!(self, Valves::SecondOrder));
        if matches!(self, Valves::TwoStage) {
            p.sv1.model = ValveModel::TwoStage;
            p.sv2.model = ValveModel::TwoStage;
        }
        p.initial_position = Trajectory::thesis().at(0.0)[0];
        p
    }
}

/// One timed run.
pub struct Run {
    pub cpu: f64,
    pub positions: Vec<f64>,
    pub p1: Vec<f64>,
    pub p2: Vec<f64>,
    /// CPU time of each 1 ms period: the step and the reading of the outputs.
    pub step_costs: Vec<f64>,
    pub states: usize,
    pub stats: SolverStats,
}

/// The moves under 1 kHz P control for `seconds` with the parameters `p`.
pub fn run(p: &Params, seconds: f64) -> Result<Run, String> {
    let mut sim = Simulation::new(p).map_err(|e| e.to_string())?;
    let trajectory = Trajectory::thesis();
    let reference = |t: f64| trajectory.at(t)[0];
    let mut law = Proportional { kp: KP };
    let timing = Timing {
        period: SAMPLE_PERIOD,
        substeps: 1,
        computation_delay: 0.0,
    };
    let mut step_costs = Vec::with_capacity((seconds / SAMPLE_PERIOD) as usize + 1);
    let mut last = None::<f64>;
    let start = cpu::thread_seconds();
    let trace = run_loop(
        &mut sim,
        &mut |t, m, _| {
            // the time since the previous sample is that period's step and output read
            let now = cpu::thread_seconds();
            if let Some(l) = last {
                step_costs.push(now - l);
            }
            let u = law.update(t, reference(t), m);
            last = Some(cpu::thread_seconds());
            u
        },
        &reference,
        seconds,
        &timing,
    )
    .map_err(|e| e.to_string())?;
    let end = cpu::thread_seconds();
    if let Some(l) = last {
        step_costs.push(end - l);
    }
    Ok(Run {
        cpu: end - start,
        positions: trace.iter().map(|s| s.out.y).collect(),
        p1: trace.iter().map(|s| s.out.p1).collect(),
        p2: trace.iter().map(|s| s.out.p2).collect(),
        step_costs,
        states: sim.bench().n_states(),
        stats: sim.stats,
    })
}

/// Largest absolute difference of two equally sampled series.
pub fn max_deviation(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Value at fraction `q` of the sorted sample (nearest rank).
fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len()) - 1;
    sorted[i]
}

fn per_second(count: usize, seconds: f64) -> f64 {
    count as f64 / seconds
}

/// The judge of every method's accuracy: diffsol's ESDIRK34 at rtol 1e-9 (independent
/// of our own integrator), one run per valve model.
fn reference_run(valves: Valves, seconds: f64) -> Result<Run, String> {
    let mut p = valves.params();
    p.solver.rtol = RTOL_REFERENCE;
    set_adaptive_method(Method::Esdirk34);
    run(&p, seconds)
}

fn valve_row(
    valves: Valves,
    method: Method,
    seconds: f64,
    reference: &Run,
) -> Result<Value, String> {
    let mut p = valves.params();
    p.solver.rtol = RTOL;
    set_adaptive_method(method);
    let fast = run(&p, seconds)?;
    let err = max_deviation(&fast.positions, &reference.positions);
    let err_p = max_deviation(&fast.p1, &reference.p1).max(max_deviation(&fast.p2, &reference.p2));
    let s = fast.stats;
    let speed = seconds / fast.cpu;
    println!(
        "{:>13} valves, {:16}: {:2} states, {speed:6.2} simulated s per CPU s; per simulated s: \
         {:6.0} steps, {:7.0} RHS, {:5.0} Jacobians, {:5.0} LU; max |y - y(ref)| = {:.4} um, \
         max |P - P(ref)| = {:.4} bar",
        valves.name(),
        format!("{method:?}"),
        fast.states,
        per_second(s.steps, seconds),
        per_second(s.rhs_evaluations, seconds),
        per_second(s.jacobian_evaluations, seconds),
        per_second(s.factorisations, seconds),
        err * 1e6,
        err_p * 1e-5
    );
    Ok(json!({
        "valves": valves.name(),
        "method": format!("{method:?}"),
        "states": fast.states,
        "simulated_seconds": seconds,
        "cpu_seconds": fast.cpu,
        "sim_s_per_cpu_s": speed,
        "steps_per_s": per_second(s.steps, seconds),
        "rhs_per_s": per_second(s.rhs_evaluations, seconds),
        "jacobians_per_s": per_second(s.jacobian_evaluations, seconds),
        "factorisations_per_s": per_second(s.factorisations, seconds),
        "max_position_error_m": err,
        "max_pressure_error_pa": err_p,
        "reference": "Esdirk34 (diffsol)",
        "reference_rtol": RTOL_REFERENCE,
        "reference_cpu_seconds": reference.cpu,
    }))
}

/// The peer at rtol 1e-6 against its own rtol 1e-9 run, and our static-valve speed over
/// its speed; `Value::String` saying why when the peer cannot run.
fn peer_row(seconds: f64, ours: f64) -> Value {
    let result = peer::Peer::locate().and_then(|peer| {
        let fast = peer.run(seconds, RTOL, KP)?;
        let reference = peer.run(seconds, RTOL_REFERENCE, KP)?;
        Ok((fast, reference))
    });
    match result {
        Ok((fast, reference)) => {
            let err = max_deviation(&fast.positions, &reference.positions);
            let speed = seconds / fast.cpu;
            println!(
                "  scipy peer (static valves): {speed:7.3} simulated s per CPU s; per simulated s: \
                 {:7.0} steps, {:8.0} RHS, {:6.0} Jacobians; max |y - y(rtol 1e-9)| = {:.4} um",
                fast.steps as f64 / seconds,
                fast.rhs as f64 / seconds,
                fast.jacobians as f64 / seconds,
                err * 1e6
            );
            println!(
                "  speed ratio, HydroBench static valves / scipy peer: {:.1}",
                ours / speed
            );
            json!({
                "simulated_seconds": seconds,
                "cpu_seconds": fast.cpu,
                "sim_s_per_cpu_s": speed,
                "steps_per_s": fast.steps as f64 / seconds,
                "rhs_per_s": fast.rhs as f64 / seconds,
                "jacobians_per_s": fast.jacobians as f64 / seconds,
                "max_position_error_m": err,
                "speed_ratio": ours / speed,
            })
        }
        Err(why) => {
            println!("  scipy peer: not run: {why}");
            Value::String(format!("not run: {why}"))
        }
    }
}

/// Cost of each 1 ms step in the fixed-step mode over `seconds` of the moves, and its
/// accuracy against the adaptive run at rtol 1e-6.
fn realtime_row(valves: Valves, fixed_step: f64, seconds: f64) -> Result<Value, String> {
    let mut p = valves.params();
    p.solver.rtol = RTOL;
    let adaptive = run(&p, seconds)?;
    p.solver.fixed_step = fixed_step;
    let fixed = run(&p, seconds)?;
    let mut costs = fixed.step_costs.clone();
    costs.sort_by(f64::total_cmp);
    let dy = max_deviation(&fixed.positions, &adaptive.positions);
    let dp = max_deviation(&fixed.p1, &adaptive.p1).max(max_deviation(&fixed.p2, &adaptive.p2));
    let [median, p999, max] = [0.5, 0.999, 1.0].map(|q| percentile(&costs, q));
    println!(
        "{:>13} valves, fixed step {:.0} us: CPU per 1 ms step median {:.1} us, p99.9 {:.1} us, \
         max {:.1} us over {} steps; max |dy| {:.2} um, max |dP| {:.3} bar vs adaptive",
        valves.name(),
        fixed_step * 1e6,
        median * 1e6,
        p999 * 1e6,
        max * 1e6,
        costs.len(),
        dy * 1e6,
        dp * 1e-5
    );
    Ok(json!({
        "valves": valves.name(),
        "fixed_step_s": fixed_step,
        "steps": costs.len(),
        "cpu_per_step_median_s": median,
        "cpu_per_step_p999_s": p999,
        "cpu_per_step_max_s": max,
        "max_position_deviation_m": dy,
        "max_pressure_deviation_pa": dp,
    }))
}

/// What `hbench bench` runs.
pub struct Request<'a> {
    /// Simulated time of each throughput run (s); 0 skips them and the peer.
    pub seconds: f64,
    /// Simulated time of the real-time cost runs (s).
    pub realtime_seconds: f64,
    /// Fixed steps of the real-time runs with static and with two-stage valves (s).
    pub static_step: f64,
    pub two_stage_step: f64,
    pub json: Option<&'a std::path::Path>,
}

pub fn main(req: &Request) -> Result<(), String> {
    let seconds = req.seconds;
    let mut valves = Vec::new();
    let mut peer = Value::Null;
    if seconds > 0.0 {
        println!(
            "mode 3, thesis bench, 7th-order +-10 mm moves, P control Kp = {KP} V/m at 1 kHz, \
             {seconds} s, rtol {RTOL:e} vs {RTOL_REFERENCE:e}; CPU time of this thread"
        );
        for v in [Valves::Static, Valves::SecondOrder, Valves::TwoStage] {
            let reference = reference_run(v, seconds)?;
            // the methods before issue 13 and ours, back to back
            for m in METHODS {
                valves.push(valve_row(v, m, seconds, &reference)?);
            }
        }
        // ours, static valves: the first row's method list puts it last
        let ours = valves[METHODS.len() - 1]["sim_s_per_cpu_s"]
            .as_f64()
            .unwrap_or(f64::NAN);
        peer = peer_row(seconds, ours);
    }
    set_adaptive_method(Method::FilteredEsdirk34);
    println!(
        "real-time mode, {} s of the moves, against the adaptive run at rtol {RTOL:e}:",
        req.realtime_seconds
    );
    let mut realtime = Vec::new();
    for (v, h) in [
        (Valves::Static, req.static_step),
        (Valves::TwoStage, req.two_stage_step),
    ] {
        realtime.push(realtime_row(v, h, req.realtime_seconds)?);
    }
    let all = json!({"valves": valves, "peer": peer, "realtime": realtime});
    if let Some(path) = req.json {
        std::fs::write(path, serde_json::to_string_pretty(&all).unwrap_or_default())
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_take_the_nearest_rank() {
        let v: Vec<f64> = (1..=1000).map(f64::from).collect();
        assert_eq!(percentile(&v, 0.5), 500.0);
        assert_eq!(percentile(&v, 0.999), 999.0);
        assert_eq!(percentile(&v, 1.0), 1000.0);
        assert!(percentile(&[], 0.5).is_nan());
    }
}
