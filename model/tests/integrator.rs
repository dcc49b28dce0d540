//! Our adaptive ESDIRK (`solver::adaptive`) against exact solutions of stiff problems,
//! its coloured finite-difference Jacobian against dense differences on the bench, the
//! bench it integrates against diffsol at rtol 1e-9, and rollback with the carried
//! Jacobian bit for bit.

mod common;

use hbmodel::control::trajectory::Trajectory;
use hbmodel::control::{run_closed_loop, Proportional, SAMPLE_PERIOD};
use hbmodel::solver::adaptive::{self, Memory, Workspace};
use hbmodel::solver::jacobian::Colouring;
use hbmodel::solver::{set_adaptive_method, Method, SolverStats, Tolerances};
use hbmodel::{Mode, Params, Simulation};

fn tolerances(n: usize, rtol: f64) -> Tolerances {
    Tolerances {
        rtol,
        atol: vec![rtol; n],
        fixed_step: 0.0,
    }
}

/// Integrate `f` over [0, t_end] in intervals of `interval`, carrying step and memory as
/// the bench does; the state at t_end and the counters.
fn solve<F>(f: &F, x0: &[f64], t_end: f64, interval: f64, rtol: f64) -> (Vec<f64>, SolverStats)
where
    F: Fn(f64, &[f64], &mut [f64]),
{
    let n = x0.len();
    let mut x = x0.to_vec();
    let mut ws = Workspace::new(Colouring::dense(n));
    let (mut step, mut mem) = (None, Memory::default());
    let mut stats = SolverStats::default();
    let tol = tolerances(n, rtol);
    let steps = (t_end / interval).round() as usize;
    for k in 0..steps {
        let (t0, t1) = (k as f64 * interval, (k + 1) as f64 * interval);
        adaptive::integrate(
            f,
            None,
            &mut x,
            t0,
            t1,
            &tol,
            &vec![1.0; n],
            &mut step,
            &mut mem,
            &mut ws,
            &mut stats,
        )
        .unwrap();
    }
    (x, stats)
}

/// Prothero-Robinson: y' = lambda (y - g(t)) + g'(t), exact y = g(t) = sin t from
/// y(0) = 0, for any lambda. Very stiff (lambda = -1e6): an L-stable method must follow
/// g with steps far above 1/|lambda|, and the filtered estimate must let it.
#[test]
fn prothero_robinson_is_followed_with_large_steps() {
    for lambda in [-1e2, -1e6] {
        let f = move |t: f64, y: &[f64], dy: &mut [f64]| {
            dy[0] = lambda * (y[0] - t.sin()) + t.cos();
        };
        let (y, stats) = solve(&f, &[0.0], 2.0, 2.0, 1e-8);
        let err = (y[0] - 2f64.sin()).abs();
        assert!(err < 1e-7, "lambda {lambda}: error {err:e}");
        // a step limited by 1/|lambda| would need millions of steps at -1e6
        assert!(stats.steps < 2000, "lambda {lambda}: {stats:?}");
    }
}

/// x1' = -a (x1 - cos t), x2' = x1 from (1, 0): exact solution in closed form.
#[test]
fn stiff_linear_system_meets_its_exact_solution_across_many_intervals() {
    let a = 1e5;
    let f = move |t: f64, x: &[f64], dx: &mut [f64]| {
        dx[0] = -a * (x[0] - t.cos());
        dx[1] = x[0];
    };
    let exact = |t: f64| {
        let c = 1.0 / (a * a + 1.0);
        let x1 = c * (-a * t).exp() + (a * a * t.cos() + a * t.sin()) * c;
        let x2 = c * (1.0 - (-a * t).exp()) / a + (a * a * t.sin() + a * (1.0 - t.cos())) * c;
        [x1, x2]
    };
    // one interval, and 1000 of 1 ms with step and Jacobian carried
    for interval in [1.0, 1e-3] {
        let (x, stats) = solve(&f, &[1.0, 0.0], 1.0, interval, 1e-8);
        let e = exact(1.0);
        // global error within 100 rtol (measured: 2e-7 in x2, the integral, 2e-9 in x1)
        assert!((x[1] - e[1]).abs() < 1e-6, "{interval}: {x:?} vs {e:?}");
        assert!((x[0] - e[0]).abs() < 1e-7, "{interval}: {x:?} vs {e:?}");
        // the fast mode (1e-5 s) does not set the step: well under one per 10 us
        assert!(stats.steps < 5000, "{interval}: {stats:?}");
        // the Jacobian (constant here) is formed once and carried, again only when Newton
        // slows down as h moves away from the h of the LU
        assert!(stats.jacobian_evaluations <= 3, "{interval}: {stats:?}");
    }
}

/// Order: on a smooth non-stiff problem the global error falls like steps^-3 (the
/// method's order), measured over a tolerance sweep.
#[test]
fn observed_order_is_three() {
    // y1' = y2, y2' = -y1 + 0.1 sin(2 t): a forced oscillator, exact solution known
    let f = |t: f64, y: &[f64], dy: &mut [f64]| {
        dy[0] = y[1];
        dy[1] = -y[0] + 0.1 * (2.0 * t).sin();
    };
    // y = (1 + 0.2/3) sin t ... from y(0) = 0, y'(0) = 1: y = A sin t - (0.1/3) sin 2t
    let exact = |t: f64| (1.0 + 0.2 / 3.0) * t.sin() - 0.1 / 3.0 * (2.0 * t).sin();
    let mut points = Vec::new();
    for rtol in [1e-5, 1e-7, 1e-9] {
        let (y, stats) = solve(&f, &[0.0, 1.0], 10.0, 10.0, rtol);
        points.push(((stats.steps as f64).ln(), (y[0] - exact(10.0)).abs().ln()));
    }
    let slope = -(points[2].1 - points[0].1) / (points[2].0 - points[0].0);
    assert!(
        slope > 2.5 && slope < 4.0,
        "observed order {slope}: {points:?}"
    );
}

/// 0.25 s of a 7th-order -10 -> +10 mm move under 1 kHz P control, mode 3, thesis bench.
fn move_run(p: &Params, method: Method, rtol: f64) -> (Vec<[f64; 3]>, SolverStats) {
    set_adaptive_method(method);
    let mut p = p.clone();
    p.solver.rtol = rtol;
    let run = common::move_run(&p, 0.25);
    set_adaptive_method(Method::FilteredEsdirk34);
    run
}

#[test]
fn bench_matches_diffsol_at_rtol_1e_9() {
    let p = Params::thesis_bench(Mode::ThreeWay);
    let (reference, _) = move_run(&p, Method::Esdirk34, 1e-9);
    let (ours, stats) = move_run(&p, Method::FilteredEsdirk34, 1e-6);
    let dev = |i: usize| {
        reference
            .iter()
            .zip(&ours)
            .map(|(a, b)| (a[i] - b[i]).abs())
            .fold(0.0, f64::max)
    };
    assert!(dev(0) < 0.1e-6, "position off by {} m", dev(0));
    let dp = dev(1).max(dev(2));
    assert!(dp < 0.05e5, "pressure off by {dp} Pa");
    // our path ran: Jacobians carried, far fewer than one per interval
    assert!(stats.jacobian_evaluations < 100, "{stats:?}");
    assert!(ours.last().unwrap()[0] > 0.0099, "{:?}", ours.last());
}

#[test]
fn coloured_jacobian_equals_dense_differences_on_the_bench() {
    for valves in ["static", "two_stage"] {
        let mut p = Params::thesis_bench(Mode::ThreeWay);
        if valves == "two_stage" {
            p.sv1.model = hbmodel::params::ValveModel::TwoStage;
            p.sv2.model = hbmodel::params::ValveModel::TwoStage;
        }
        let mut sim = Simulation::new(&p).unwrap();
        let n = sim.bench().n_states();
        let (atol, scale) = sim.bench().state_scales(1e-6);
        assert_eq!(atol.len(), n);
        let colouring = hbmodel::bench::probe_colouring(sim.bench(), &scale);
        assert!(
            colouring.colours() < n / 2,
            "{valves}: {} colours for {n} states",
            colouring.colours()
        );
        let dense = Colouring::dense(n);
        // states along a short run under changing commands
        for (k, u) in [(0, 2.0), (1, -3.0), (2, 0.5)] {
            let inputs = hbmodel::Inputs {
                u1: u,
                u2: -u,
                f_ext: 100.0 * k as f64,
            };
            sim.set_inputs(inputs);
            sim.advance_to(0.005 * (k + 1) as f64).unwrap();
            let x = sim.state().x.clone();
            let bench = sim.bench();
            // one compiled body for f(x) here and inside the differences
            let f: hbmodel::solver::jacobian::DynRhs = &|_t, x, dx| {
                bench.derivatives(x, &inputs, dx);
            };
            let mut fx = vec![0.0; n];
            f(0.0, &x, &mut fx);
            let (mut s, mut fh) = (vec![0.0; n], vec![0.0; n]);
            let (mut jc, mut jd) = (vec![0.0; n * n], vec![0.0; n * n]);
            colouring.finite_differences(f, 0.0, &x, &fx, &scale, &mut jc, &mut s, &mut fh);
            dense.finite_differences(f, 0.0, &x, &fx, &scale, &mut jd, &mut s, &mut fh);
            for i in 0..n {
                for j in 0..n {
                    assert_eq!(
                        jc[i * n + j],
                        jd[i * n + j],
                        "{valves}, state {k}: entry ({i}, {j})"
                    );
                }
            }
        }
    }
}

#[test]
fn rollback_with_the_carried_jacobian_is_bit_exact() {
    let p = Params::thesis_bench(Mode::ThreeWay);
    let tr = Trajectory::new(&[(0.0, 0.0, 0.005, 0.05)]).unwrap();
    let run = |sim: &mut Simulation, t_end: f64| {
        run_closed_loop(
            sim,
            &mut Proportional { kp: 1169.0 },
            &|t| tr.at(t)[0],
            t_end,
            SAMPLE_PERIOD,
            1,
        )
        .unwrap()
        .iter()
        .map(|s| s.out.y.to_bits())
        .collect::<Vec<u64>>()
    };
    let mut sim = Simulation::new(&p).unwrap();
    run(&mut sim, 0.03);
    let saved = sim.state().clone();
    assert!(
        !saved.integrator.jacobian.is_empty(),
        "a Jacobian is carried"
    );
    let first = run(&mut sim, 0.06);
    // the same simulation rolled back (its LU now belongs to a later Jacobian)
    sim.set_state(saved.clone()).unwrap();
    assert_eq!(run(&mut sim, 0.06), first);
    // a fresh simulation, its LU rebuilt from the state
    let mut other = Simulation::new(&p).unwrap();
    other.set_state(saved.clone()).unwrap();
    assert_eq!(run(&mut other, 0.06), first);
    // a state whose memory cannot be this integrator's is refused
    let mut bad = saved;
    bad.integrator.jacobian.pop();
    assert!(other.set_state(bad).is_err());
}
