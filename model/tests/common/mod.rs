//! What several integration tests run: the thesis's 7th-order move under its 1 kHz
//! proportional control.

use hbmodel::control::trajectory::Trajectory;
use hbmodel::control::{run_closed_loop, Proportional, SAMPLE_PERIOD};
use hbmodel::solver::SolverStats;
use hbmodel::{Params, Simulation};

/// A 7th-order move from -10 mm to +10 mm in 0.1 s starting at 20 ms, `duration` s in
/// all, under P control at Kp 1169 V/m: the sampled y, P1, P2 and the solver's counts.
pub fn move_run(p: &Params, duration: f64) -> (Vec<[f64; 3]>, SolverStats) {
    let tr = Trajectory::new(&[(0.02, -0.01, 0.01, 0.1)]).unwrap();
    let mut p = p.clone();
    p.initial_position = -0.01;
    let mut sim = Simulation::new(&p).unwrap();
    let trace = run_closed_loop(
        &mut sim,
        &mut Proportional { kp: 1169.0 },
        &|t| tr.at(t)[0],
        duration,
        SAMPLE_PERIOD,
        1,
    )
    .unwrap();
    let out = trace
        .iter()
        .map(|s| [s.out.y, s.out.p1, s.out.p2])
        .collect();
    (out, sim.stats)
}
