//! The fixed-step real-time mode (`solver.fixed_step`) against the adaptive solver on a
//! short +-10 mm move under the thesis's 1 kHz proportional control: position within
//! 1 % of the move amplitude, pressures within 2 bar (issue 13's accuracy criterion).

mod common;

use hbmodel::params::ValveModel;
use hbmodel::{Mode, Params, Simulation};

/// One 7th-order move from -10 mm to +10 mm in 0.1 s starting at 20 ms, 0.2 s in all.
fn run(p: &Params) -> (Vec<[f64; 3]>, hbmodel::solver::SolverStats) {
    common::move_run(p, 0.2)
}

fn compare(p: &Params, step: f64) {
    let (adaptive, _) = run(p);
    let mut fixed = p.clone();
    fixed.solver.fixed_step = step;
    let (rt, stats) = run(&fixed);
    // the fixed-step path ran: one Jacobian per interval, steps no longer than `step`
    assert!(stats.jacobian_evaluations >= 200, "{stats:?}");
    assert!(stats.steps as f64 >= 0.2 / step, "{stats:?}");
    let dev = |i: usize| {
        adaptive
            .iter()
            .zip(&rt)
            .map(|(a, b)| (a[i] - b[i]).abs())
            .fold(0.0, f64::max)
    };
    assert!(dev(0) < 0.01 * 0.02, "position off by {} m", dev(0));
    assert!(
        dev(1).max(dev(2)) < 2e5,
        "pressure off by {} Pa",
        dev(1).max(dev(2))
    );
    // the move happened
    assert!(rt.last().unwrap()[0] > 0.009, "{:?}", rt.last());
}

#[test]
fn fixed_step_follows_the_adaptive_solver_with_reduced_valves() {
    compare(&Params::thesis_bench(Mode::ThreeWay), 5e-4);
}

#[test]
fn fixed_step_follows_the_adaptive_solver_with_two_stage_valves() {
    let mut p = Params::thesis_bench(Mode::ThreeWay);
    p.sv1.model = ValveModel::TwoStage;
    p.sv2.model = ValveModel::TwoStage;
    compare(&p, 1e-4);
}

#[test]
fn a_tiny_interval_leaves_the_fixed_step_run_unchanged() {
    let mut p = Params::thesis_bench(Mode::ThreeWay);
    p.solver.fixed_step = 5e-4;
    let mut a = Simulation::new(&p).unwrap();
    let mut b = Simulation::new(&p).unwrap();
    let inputs = hbmodel::Inputs {
        u1: 1.0,
        u2: -1.0,
        f_ext: 0.0,
    };
    a.set_inputs(inputs);
    b.set_inputs(inputs);
    b.advance_to(1e-15).unwrap();
    for k in 1..=20 {
        a.advance_to(k as f64 * 1e-3).unwrap();
        b.advance_to(k as f64 * 1e-3).unwrap();
    }
    let (ya, yb) = (a.outputs().y, b.outputs().y);
    assert!((ya - yb).abs() < 1e-9, "{ya} vs {yb}");
    assert!(
        ya - p.initial_position > 1e-6,
        "the piston did not move: {ya}"
    );
}
