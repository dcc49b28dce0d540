//! Stiff integration: our ESDIRK with a filtered error estimate and carried Jacobian
//! ([`adaptive`], the default), diffsol's ESDIRK34 and BDF (kept selectable for
//! side-by-side benchmarks), or the fixed-step real-time method ([`fixed_step`]).
//!
//! The bench is stiff: tiny manifold port volumes against servovalve orifices give time
//! constants of ~10 us, while the piston moves over tens of milliseconds. L-stable
//! one-step methods with a dense LU serve at this size (20-40 states); a one-step method
//! does not restart at order 1 at every 1 kHz input jump as BDF does.
//!
//! The right-hand side is piecewise smooth (sign of a pressure drop, saturations, end
//! stops), which defeats diffsol's NaN-propagation sparsity guess; we give it a
//! Jacobian by one-sided finite differences with per-state scales instead, coloured over
//! a probed sparsity pattern on our own integrator's path ([`jacobian`]).
//!
//! One call integrates over one interval with constant inputs. diffsol starts a fresh
//! solver there; our integrator carries its Jacobian and step in a [`adaptive::Memory`]
//! that the caller keeps with the state, so a restored state replays bit for bit.

use std::cell::RefCell;

pub mod adaptive;
pub mod dense_lu;
mod esdirk_tableau;
pub mod fixed_step;
pub mod jacobian;

use diffsol::{
    NalgebraLU, NalgebraMat, OdeBuilder, OdeSolverMethod, OdeSolverState, OdeSolverStopReason,
    Tableau, Vector,
};

/// Why an integration failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolverError {
    #[error("the integrator failed at t = {t} s: {message}")]
    Failed { t: f64, message: String },
    #[error("the state became non-finite at t = {t} s")]
    NonFinite { t: f64 },
    /// Our integrator's Newton kept failing with fresh Jacobians
    /// ([`adaptive::MAX_FRESH_FAILURES`]); [`advance`] retries the interval with diffsol.
    #[error("Newton stalled at t = {t} s")]
    Stalled { t: f64 },
    #[error("invalid time interval [{t0}, {t1}]")]
    BadInterval { t0: f64, t1: f64 },
}

/// Counters of one or more integrations.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SolverStats {
    pub steps: usize,
    /// Calls of the right-hand side, those the finite-difference Jacobian makes included.
    pub rhs_evaluations: usize,
    /// Full Jacobians formed (each one costs n + 1 right-hand sides by differences).
    pub jacobian_evaluations: usize,
    /// LU factorisations of the Newton matrix.
    pub factorisations: usize,
}

/// Settings of one integration.
#[derive(Debug, Clone)]
pub struct Tolerances {
    pub rtol: f64,
    pub atol: Vec<f64>,
    /// Above 0, the fixed-step real-time method with steps of this size (s) instead of
    /// the adaptive solver ([`fixed_step`]); 0 keeps the adaptive solver.
    pub fixed_step: f64,
}

/// Shortest carried step, as a fraction of the next interval, used to seed it: shorter
/// ones are dropped for diffsol's own start-up estimate. 1e-9 keeps every step a stiff
/// interval of the bench carries (~1e-7 s over 1e-3 s intervals) and drops a 1e-15 s one.
const MIN_CARRIED_STEP: f64 = 1e-9;

/// diffsol's smallest step (its `OdeSolverOptions::min_timestep` default): a shorter
/// interval makes every method fail with "step size is too small".
const DIFFSOL_MIN_STEP: f64 = 1e-13;

/// Relative perturbation of the finite-difference Jacobian: sqrt of machine epsilon.
const FD_EPS: f64 = 1.490_116_119_384_765_6e-8;

/// Integrate dx/dt = f(t, x) from `t0` to `t1`, overwriting `x` with the state at `t1`.
/// `scale[i]` is the typical magnitude of state i, used to size finite differences.
pub fn integrate<F>(
    f: F,
    x: &mut [f64],
    t0: f64,
    t1: f64,
    tol: &Tolerances,
    scale: &[f64],
    stats: &mut SolverStats,
) -> Result<(), SolverError>
where
    F: Fn(f64, &[f64], &mut [f64]),
{
    integrate_from(f, x, t0, t1, tol, scale, stats, &mut None)
}

/// [`integrate`], starting with the step size `step` when given, and leaving in it the
/// step size the solver would take next. A run of short intervals (communication steps)
/// then keeps its step size from one interval to the next instead of restarting from a
/// cold-start estimate each time, which on the bench costs tens of tiny steps per
/// millisecond. Our integrator runs here with a dense finite-difference Jacobian and no
/// memory beyond the step; [`advance`] carries more.
#[allow(clippy::too_many_arguments)]
pub fn integrate_from<F>(
    f: F,
    x: &mut [f64],
    t0: f64,
    t1: f64,
    tol: &Tolerances,
    scale: &[f64],
    stats: &mut SolverStats,
    step: &mut Option<f64>,
) -> Result<(), SolverError>
where
    F: Fn(f64, &[f64], &mut [f64]),
{
    let carry = Carry {
        step,
        memory: &mut adaptive::Memory::default(),
        workspace: &mut None,
        jacobian: None,
    };
    advance(&f, x, t0, t1, tol, scale, stats, carry)
}

/// What a model keeps between intervals for the integrator: the proposed step and the
/// memory (both part of its state), the workspace (buffers and the LU, derived), and an
/// exact Jacobian when it has one.
pub struct Carry<'a, 'j> {
    pub step: &'a mut Option<f64>,
    pub memory: &'a mut adaptive::Memory,
    /// Built on first use with a dense finite-difference Jacobian when None.
    pub workspace: &'a mut Option<adaptive::Workspace>,
    pub jacobian: Option<jacobian::ExactJacobian<'j>>,
}

/// Integrate over [t0, t1] with the method selected ([`adaptive_method`], or the fixed
/// step when `tol.fixed_step` > 0), carrying `carry` across calls.
#[allow(clippy::too_many_arguments)]
pub fn advance<F>(
    f: &F,
    x: &mut [f64],
    t0: f64,
    t1: f64,
    tol: &Tolerances,
    scale: &[f64],
    stats: &mut SolverStats,
    carry: Carry,
) -> Result<(), SolverError>
where
    F: Fn(f64, &[f64], &mut [f64]),
{
    if !t0.is_finite() || !t1.is_finite() || t1 < t0 {
        return Err(SolverError::BadInterval { t0, t1 });
    }
    // an interval of a few ulps (two communication points that round to the same
    // instant) holds nothing to integrate, and diffsol refuses a stop time it is at
    if t1 - t0 <= 4.0 * f64::EPSILON * t0.abs().max(1e-3) {
        return Ok(());
    }
    if tol.fixed_step > 0.0 {
        let colouring = carry.workspace.as_ref().map(|w| w.colouring());
        return fixed_step::integrate_coloured(
            f,
            x,
            t0,
            t1,
            tol.fixed_step,
            tol,
            scale,
            stats,
            colouring,
        );
    }
    // every method refuses a step below diffsol's minimum (an fmi2DoStep by 1e-15 s):
    // such an interval is one explicit Euler step, stable and exact to O(h^2) there since
    // h |lambda| stays below 1e-6 for the bench's fastest modes (~1e7 1/s, the two-stage
    // valve's pilot)
    if t1 - t0 < DIFFSOL_MIN_STEP {
        let mut dx = vec![0.0; x.len()];
        f(t0, x, &mut dx);
        stats.rhs_evaluations += 1;
        stats.steps += 1;
        x.iter_mut()
            .zip(&dx)
            .for_each(|(xi, d)| *xi += (t1 - t0) * d);
        if x.iter().any(|v| !v.is_finite()) {
            return Err(SolverError::NonFinite { t: t1 });
        }
        return Ok(());
    }
    match adaptive_method() {
        Method::FilteredEsdirk34 => {
            let ws = carry.workspace.get_or_insert_with(|| {
                adaptive::Workspace::new(jacobian::Colouring::dense(x.len()))
            });
            let mut y = x.to_vec();
            let r = adaptive::integrate(
                f,
                carry.jacobian,
                &mut y,
                t0,
                t1,
                tol,
                scale,
                carry.step,
                carry.memory,
                ws,
                stats,
            );
            match r {
                Ok(()) => {
                    x.copy_from_slice(&y);
                    Ok(())
                }
                // the interval again, from its start, with diffsol's ESDIRK34: a
                // deterministic function of (x, step), so a restored state replays it
                Err(SolverError::Stalled { .. }) => diffsol_integrate(
                    f,
                    Method::Esdirk34,
                    x,
                    t0,
                    t1,
                    tol,
                    scale,
                    stats,
                    carry.step,
                ),
                // a failure leaves x where it was
                Err(e) => Err(e),
            }
        }
        m => diffsol_integrate(f, m, x, t0, t1, tol, scale, stats, carry.step),
    }
}

/// diffsol's ESDIRK34 or BDF over one interval, from a fresh solver seeded with `step`.
#[allow(clippy::too_many_arguments)]
fn diffsol_integrate<F>(
    f: &F,
    method: Method,
    x: &mut [f64],
    t0: f64,
    t1: f64,
    tol: &Tolerances,
    scale: &[f64],
    stats: &mut SolverStats,
    step: &mut Option<f64>,
) -> Result<(), SolverError>
where
    F: Fn(f64, &[f64], &mut [f64]),
{
    let n = x.len();
    let calls = RefCell::new(0usize);
    let jacobians = RefCell::new(0usize);
    // f at the point the Jacobian is taken, kept across its n columns: diffsol asks for
    // them one by one at the same (t, y), and f(y) is the same for all of them
    let base = RefCell::new((f64::NAN, vec![f64::NAN; n], vec![0.0; n]));
    let shifted = RefCell::new((vec![0.0; n], vec![0.0; n]));
    let rhs = |y: &[f64], _p: &[f64], t: f64, dy: &mut [f64]| {
        *calls.borrow_mut() += 1;
        f(t, y, dy);
    };
    // Directional difference J*v ~ (f(x + h v) - f(x)) / h, with h sized from the state
    // scales of the components v touches (diffsol asks column by column, v = e_j).
    let jac = |y: &[f64], _p: &[f64], t: f64, v: &[f64], jv: &mut [f64]| {
        let mut h = 0.0f64;
        for j in 0..n {
            if v[j] != 0.0 {
                h = h.max(FD_EPS * y[j].abs().max(scale[j]) / v[j].abs());
            }
        }
        if h == 0.0 {
            jv.iter_mut().for_each(|e| *e = 0.0);
            return;
        }
        let mut base = base.borrow_mut();
        let (t_b, y_b, f_b) = &mut *base;
        if *t_b != t || y_b.as_slice() != y {
            *t_b = t;
            y_b.copy_from_slice(y);
            f(t, y, f_b);
            *calls.borrow_mut() += 1;
            *jacobians.borrow_mut() += 1;
        }
        let mut shifted = shifted.borrow_mut();
        let (yh, f_h) = &mut *shifted;
        for j in 0..n {
            yh[j] = y[j] + h * v[j];
        }
        f(t, yh, f_h);
        *calls.borrow_mut() += 1;
        for i in 0..n {
            jv[i] = (f_h[i] - f_b[i]) / h;
        }
    };
    let x0 = x.to_vec();
    let problem = OdeBuilder::<NalgebraMat<f64>>::new()
        .t0(t0)
        .rtol(tol.rtol)
        .atol(tol.atol.iter().copied())
        .rhs_implicit(rhs, jac)
        .init(move |_p, _t, y| y.copy_from_slice(&x0), n)
        .build()
        .map_err(|e| SolverError::Failed {
            t: t0,
            message: e.to_string(),
        })?;
    let fail = |e: diffsol::error::DiffsolError| SolverError::Failed {
        t: t0,
        message: e.to_string(),
    };
    // a carried step far shorter than the interval is the trace of a tiny interval
    // (fmi2DoStep by 1e-15 s), not of the dynamics: seeding with it makes diffsol give up
    // ("step size is too small") on every later interval (issue 16, item 1)
    let seed = |h: &mut f64| {
        if let Some(s) = *step {
            if s.is_finite() && s > 0.0 && s >= MIN_CARRIED_STEP * (t1 - t0) {
                *h = s;
            }
        }
    };
    // ESDIRK34, measured against BDF and TR-BDF2 on the moves (hbench bench, rtol 1e-6,
    // each against its own rtol 1e-9 run, all within 0.015 um): simulated s per CPU s
    // static / second-order / two-stage valves, BDF 11.5 / 10.4 / 1.56, TR-BDF2
    // 11.4 / 13.5 / 2.80, ESDIRK34 12.4 / 11.7 / 2.93. A one-step method does not restart
    // at order 1 at every interval as BDF does, which is what the 1 kHz input jumps cost.
    let (y, free_step, last_step, setups) = match method {
        Method::Esdirk34 => {
            let tableau = Tableau::<f64>::esdirk34();
            let mut state = problem.rk_state(&tableau).map_err(fail)?;
            seed(state.as_mut().h);
            let solver = problem
                .sdirk_solver::<NalgebraLU<f64>, _>(state, tableau)
                .map_err(fail)?;
            drive(solver, t0, t1, stats)?
        }
        _ => {
            let mut state = problem.bdf_state::<NalgebraLU<f64>>().map_err(fail)?;
            seed(state.as_mut().h);
            let solver = problem.bdf_solver::<NalgebraLU<f64>>(state).map_err(fail)?;
            drive(solver, t0, t1, stats)?
        }
    };
    *step = free_step.or(*step).or(Some(last_step));
    x.copy_from_slice(&y);
    stats.rhs_evaluations += *calls.borrow();
    stats.jacobian_evaluations += *jacobians.borrow();
    stats.factorisations += setups;
    if x.iter().any(|v| !v.is_finite()) {
        return Err(SolverError::NonFinite { t: t1 });
    }
    Ok(())
}

/// The adaptive method. Ours ([`adaptive`]) is the default; diffsol's ESDIRK34 (the one
/// before it) and BDF (the one before that) stay selectable so that `hbench bench` can
/// time them side by side in one run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    FilteredEsdirk34,
    Esdirk34,
    Bdf,
}

thread_local! {
    static SELECTED: std::cell::Cell<Method> = const { std::cell::Cell::new(Method::FilteredEsdirk34) };
}

/// Select the adaptive method for every later integration on this thread (a benchmark
/// switch: the models never call it; per thread, so tests comparing methods side by side
/// do not race).
pub fn set_adaptive_method(m: Method) {
    SELECTED.with(|s| s.set(m));
}

pub fn adaptive_method() -> Method {
    SELECTED.with(|s| s.get())
}

/// Step `solver` to `t1`; the state there, the last step it chose freely (the one that
/// lands on t1 is cut to fit, and a tiny interval has none), the last step, and its
/// Jacobian/LU setups.
fn drive<'a, Eqn, S>(
    mut solver: S,
    t0: f64,
    t1: f64,
    stats: &mut SolverStats,
) -> Result<(Vec<f64>, Option<f64>, f64, usize), SolverError>
where
    Eqn: diffsol::OdeEquations<T = f64, V = diffsol::NalgebraVec<f64>> + 'a,
    S: OdeSolverMethod<'a, Eqn>,
{
    solver.set_stop_time(t1).map_err(|e| SolverError::Failed {
        t: t0,
        message: e.to_string(),
    })?;
    let mut free_step = None;
    loop {
        let t_now = solver.state().t;
        match solver.step() {
            Ok(OdeSolverStopReason::TstopReached) => break,
            Ok(_) => {
                stats.steps += 1;
                free_step = Some(solver.state().h.abs());
            }
            Err(e) => {
                return Err(SolverError::Failed {
                    t: t_now,
                    message: e.to_string(),
                });
            }
        }
    }
    stats.steps += 1;
    let setups = solver.get_statistics().number_of_linear_solver_setups;
    let last = solver.state().h.abs();
    Ok((solver.state().y.clone_as_vec(), free_step, last, setups))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stiff_linear_system_matches_its_exact_solution() {
        // x1' = -1e5 (x1 - cos t), x2' = x1: stiff fast mode tracking a slow input
        let f = |t: f64, x: &[f64], dx: &mut [f64]| {
            dx[0] = -1e5 * (x[0] - t.cos());
            dx[1] = x[0];
        };
        let mut x = [1.0, 0.0];
        let tol = Tolerances {
            rtol: 1e-8,
            atol: vec![1e-10, 1e-10],
            fixed_step: 0.0,
        };
        let mut stats = SolverStats::default();
        integrate(f, &mut x, 0.0, 1.0, &tol, &[1.0, 1.0], &mut stats).unwrap();
        assert!((x[1] - 1f64.sin()).abs() < 1e-4, "{x:?}");
        assert!(
            stats.steps < 2000,
            "a stiff solver needs few steps: {stats:?}"
        );
    }

    #[test]
    fn bad_interval_is_an_error_not_a_panic() {
        let f = |_t: f64, _x: &[f64], dx: &mut [f64]| dx[0] = 0.0;
        let tol = Tolerances {
            rtol: 1e-6,
            atol: vec![1e-6],
            fixed_step: 0.0,
        };
        let mut x = [0.0];
        let r = integrate(
            f,
            &mut x,
            1.0,
            0.0,
            &tol,
            &[1.0],
            &mut SolverStats::default(),
        );
        assert!(matches!(r, Err(SolverError::BadInterval { .. })));
        let r = integrate(
            f,
            &mut x,
            0.0,
            f64::NAN,
            &tol,
            &[1.0],
            &mut SolverStats::default(),
        );
        assert!(r.is_err());
    }

    #[test]
    fn non_finite_state_is_reported() {
        let f =
            |_t: f64, x: &[f64], dx: &mut [f64]| dx[0] = if x[0] > 0.5 { f64::NAN } else { 1.0 };
        let tol = Tolerances {
            rtol: 1e-6,
            atol: vec![1e-6],
            fixed_step: 0.0,
        };
        let mut x = [0.0];
        let r = integrate(
            f,
            &mut x,
            0.0,
            1.0,
            &tol,
            &[1.0],
            &mut SolverStats::default(),
        );
        assert!(r.is_err(), "{x:?}");
    }
}
