//! `hbench bench`: speed of the bench model, the figures issue 2 asks to report.
//!
//! 1 s of the bench in mode 3 under proportional control following +-10 mm moves, with
//! the static and with the second-order servovalve, at rtol 1e-6; accuracy against an
//! rtol 1e-9 run of the same case.

use std::time::Instant;

use hbmodel::control::{run_closed_loop, Proportional, SAMPLE_PERIOD};
use hbmodel::{Effect, Mode, Params, Simulation};

struct Run {
    cpu: f64,
    positions: Vec<f64>,
    states: usize,
    steps: usize,
}

fn run(dynamics: bool, rtol: f64, seconds: f64) -> Result<Run, String> {
    let mut p = Params::thesis_bench(Mode::ThreeWay);
    p.effects.set(Effect::ValveDynamics, dynamics);
    p.solver.rtol = rtol;
    p.initial_position = -0.01;
    let mut sim = Simulation::new(&p).map_err(|e| e.to_string())?;
    // +-10 mm square moves every 0.25 s
    let reference = |t: f64| {
        if ((t / 0.25) as i64) % 2 == 0 {
            0.01
        } else {
            -0.01
        }
    };
    let start = Instant::now();
    let trace = run_closed_loop(
        &mut sim,
        &mut Proportional { kp: 1169.0 },
        &reference,
        seconds,
        SAMPLE_PERIOD,
        1,
    )
    .map_err(|e| e.to_string())?;
    Ok(Run {
        cpu: start.elapsed().as_secs_f64(),
        positions: trace.iter().map(|s| s.out.y).collect(),
        states: sim.bench().n_states(),
        steps: sim.stats.steps,
    })
}

pub fn main(seconds: f64, json: bool) -> Result<(), String> {
    let mut rows = Vec::new();
    for dynamics in [false, true] {
        let fast = run(dynamics, 1e-6, seconds)?;
        let reference = run(dynamics, 1e-9, seconds)?;
        let err = fast
            .positions
            .iter()
            .zip(&reference.positions)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let name = if dynamics { "second-order" } else { "static" };
        let speed = seconds / fast.cpu;
        if !json {
            println!(
                "{name:>13} valve: {} states, {} steps, {speed:.2} simulated s per CPU s, max |y - y(rtol 1e-9)| = {:.4} um",
                fast.states,
                fast.steps,
                err * 1e6
            );
        }
        rows.push(format!(
            "{{\"valve\":\"{name}\",\"states\":{},\"steps\":{},\"simulated_seconds\":{seconds},\"cpu_seconds\":{:.4},\"sim_s_per_cpu_s\":{speed:.3},\"max_position_error_m\":{err:.3e}}}",
            fast.states, fast.steps, fast.cpu
        ));
    }
    if json {
        println!("[{}]", rows.join(","));
    }
    Ok(())
}
