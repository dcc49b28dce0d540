//! Benchmark (issue 2): simulated seconds per CPU second for 1 s of the bench in mode 3
//! under proportional control following a +-10 mm move, static and second-order valve,
//! rtol 1e-6, and the deviation from a 1e-9 reference. Prints a table and JSON.
use hbmodel::control::{run_closed_loop, Proportional, SAMPLE_PERIOD};
use hbmodel::{Effect, Mode, Params, Simulation};
use std::time::Instant;

fn run(dynamics: bool, rtol: f64) -> (f64, Vec<f64>, usize) {
    let mut p = Params::thesis_bench(Mode::ThreeWay);
    p.effects.set(Effect::ValveDynamics, dynamics);
    p.solver.rtol = rtol;
    p.initial_position = -0.01;
    let mut sim = Simulation::new(&p).expect("thesis parameters are valid");
    // +-10 mm square move every 0.25 s
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
        1.0,
        SAMPLE_PERIOD,
        1,
    )
    .expect("the bench integrates");
    let cpu = start.elapsed().as_secs_f64();
    (
        cpu,
        trace.iter().map(|s| s.out.y).collect(),
        sim.bench().n_states(),
    )
}

fn main() {
    let mut rows = Vec::new();
    for dynamics in [false, true] {
        let (cpu, y, n) = run(dynamics, 1e-6);
        let (_, y_ref, _) = run(dynamics, 1e-9);
        let err = y
            .iter()
            .zip(&y_ref)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let name = if dynamics { "second-order" } else { "static" };
        println!("{name:>13} valve: {n} states, {:.1} simulated s per CPU s, max |y - y_ref(1e-9)| = {:.3} um", 1.0 / cpu, err * 1e6);
        rows.push(format!(
            "{{\"valve\":\"{name}\",\"states\":{n},\"sim_s_per_cpu_s\":{:.3},\"max_position_error_m\":{:.3e}}}",
            1.0 / cpu,
            err
        ));
    }
    println!("[{}]", rows.join(","));
}
