//! Fixed-step real-time integration: every step of the same size costs the same.
//!
//! Method: Alexander's two-stage SDIRK of order 2 (Hairer & Wanner, Solving ODEs II,
//! section IV.6, Table 6.5 with gamma = 1 - 1/sqrt 2). It is L-stable, so the ~10 us
//! manifold and valve modes are damped at any step size instead of ringing, and stiffly
//! accurate (the second stage is the new state). Both stages share the diagonal gamma,
//! so one Newton matrix I - h gamma J and one LU serve the whole step.
//!
//! Bounded cost: the Jacobian (finite differences with the state scales, as the adaptive
//! path does) and its LU are formed once at the start of each interval and then every
//! [`JACOBIAN_REFRESH`] steps, on that fixed schedule whatever the convergence; each
//! stage takes at most [`MAX_NEWTON`] simplified Newton iterations. A stage that has not
//! converged by then is an error for the caller to report, never a silent result.
//!
//! Why SDIRK2 and not backward Euler (one stage fewer): both are L-stable, SDIRK2 is of
//! order 2 (the unit test below measures the error ratio 3-5 on halving the step), and
//! the second stage reuses the first's LU. Backward Euler on the bench was not measured.

use nalgebra::{DMatrix, DVector};

use super::jacobian::Colouring;
use super::{SolverError, SolverStats, Tolerances, FD_EPS};

/// Fraction of a step by which an interval may exceed a whole number of steps and still
/// take that number: communication points in decimal seconds carry rounding errors.
const STEP_ROUNDING: f64 = 1e-9;

/// gamma = 1 - 1/sqrt(2), the L-stable choice for the two-stage SDIRK.
const GAMMA: f64 = 1.0 - std::f64::consts::FRAC_1_SQRT_2;

/// Simplified Newton iterations allowed per stage. Measured on the moves (hbench bench):
/// 3 fail at the first step from rest, 8 pass 10 s of the moves at the steps that
/// docs/realtime.md lists (the first correction from the stage's start is large; the
/// iterations then gain about two decades each).
pub const MAX_NEWTON: usize = 8;

/// Steps between Jacobian refreshes within one interval (an interval always starts
/// with a fresh one: the inputs, hence the valve openings, jump there).
pub const JACOBIAN_REFRESH: usize = 10;

/// Most fixed steps one interval may take. The mode exists for a bounded cost per
/// `doStep`: 10,000 steps cover a 1 s communication interval at 0.1 ms (the smallest step
/// docs/realtime.md needs, for the two-stage valve), about 0.2-2 s of CPU. A smaller
/// `solver.fixed_step` against a longer interval (the fuzzer's 5e-324 s made a 1 ns
/// interval an endless loop) is refused with the count it would need.
pub const MAX_STEPS_PER_INTERVAL: f64 = 1e4;

/// Integrate from `t0` to `t1` with steps of at most `h`, equal steps of
/// (t1 - t0) / ceil((t1 - t0) / h). The caller guarantees a valid interval.
#[allow(clippy::too_many_arguments)]
pub fn integrate<F>(
    f: &F,
    x: &mut [f64],
    t0: f64,
    t1: f64,
    h: f64,
    tol: &Tolerances,
    scale: &[f64],
    stats: &mut SolverStats,
) -> Result<(), SolverError>
where
    F: Fn(f64, &[f64], &mut [f64]),
{
    integrate_coloured(f, x, t0, t1, h, tol, scale, stats, None)
}

/// [`integrate`] with the Jacobian by coloured differences when `colouring` is given
/// (the model's sparsity, `solver::jacobian`): one right-hand side per colour instead of
/// one per state, the same Jacobian entries.
#[allow(clippy::too_many_arguments)]
pub fn integrate_coloured<F>(
    f: &F,
    x: &mut [f64],
    t0: f64,
    t1: f64,
    h: f64,
    tol: &Tolerances,
    scale: &[f64],
    stats: &mut SolverStats,
    colouring: Option<&Colouring>,
) -> Result<(), SolverError>
where
    F: Fn(f64, &[f64], &mut [f64]),
{
    let n = x.len();
    let span = t1 - t0;
    // a rounding error over the ratio must not add a step of a few ulps
    let steps = (span / h - STEP_ROUNDING).ceil().max(1.0);
    if steps.is_nan() || steps > MAX_STEPS_PER_INTERVAL {
        return Err(SolverError::Failed {
            t: t0,
            message: format!(
                "solver.fixed_step = {h:e} s would take {steps:e} steps over this {span:e} s \
                 interval, more than the real-time mode's {MAX_STEPS_PER_INTERVAL:e}: raise \
                 solver.fixed_step or shorten the communication step"
            ),
        });
    }
    let steps = steps as usize;
    let dt = span / steps as f64;
    let mut w = Work::new(n);
    w.colouring = colouring;
    for k in 0..steps {
        // time relative to the interval's start, so a result never depends on t0
        let t = t0 + k as f64 * dt;
        if k % JACOBIAN_REFRESH == 0 {
            w.factorise(f, t, x, dt, scale, stats)?;
        }
        // stage 1: Y1 = x + h g f(Y1)
        w.base.copy_from_slice(x);
        w.y.copy_from_slice(x);
        w.solve_stage(f, t + GAMMA * dt, dt, tol, scale, stats)?;
        // stage 2: Y2 = x + h (1 - g) f(Y1) + h g f(Y2); start Newton from Y1. f(Y1) is
        // (Y1 - x) / (h g) by stage 1's equation: no right-hand side call, and it carries
        // no more than stage 1's Newton residual (Hairer & Wanner IV.8)
        for ((b, &y1), &x0) in w.base.iter_mut().zip(&w.y).zip(x.iter()) {
            *b = x0 + (1.0 - GAMMA) / GAMMA * (y1 - x0);
        }
        w.solve_stage(f, t + dt, dt, tol, scale, stats)?;
        x.copy_from_slice(&w.y);
        stats.steps += 1;
        if x.iter().any(|v| !v.is_finite()) {
            return Err(SolverError::NonFinite { t: t + dt });
        }
    }
    Ok(())
}

/// Buffers of one interval, and the factorised Newton matrix.
struct Work<'c> {
    colouring: Option<&'c Colouring>,
    /// Row-major Jacobian the colouring fills.
    coloured: Vec<f64>,
    lu: Option<nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>>,
    jac: DMatrix<f64>,
    base: Vec<f64>,
    y: Vec<f64>,
    k1: Vec<f64>,
    fy: Vec<f64>,
    shifted: Vec<f64>,
    residual: DVector<f64>,
}

impl<'c> Work<'c> {
    fn new(n: usize) -> Work<'c> {
        Work {
            colouring: None,
            coloured: Vec::new(),
            lu: None,
            jac: DMatrix::zeros(n, n),
            base: vec![0.0; n],
            y: vec![0.0; n],
            k1: vec![0.0; n],
            fy: vec![0.0; n],
            shifted: vec![0.0; n],
            residual: DVector::zeros(n),
        }
    }

    /// J by one-sided differences at (t, x), then the LU of I - h gamma J.
    fn factorise<F>(
        &mut self,
        f: &F,
        t: f64,
        x: &[f64],
        h: f64,
        scale: &[f64],
        stats: &mut SolverStats,
    ) -> Result<(), SolverError>
    where
        F: Fn(f64, &[f64], &mut [f64]),
    {
        let n = x.len();
        f(t, x, &mut self.fy);
        if let Some(c) = self.colouring {
            self.coloured.resize(n * n, 0.0);
            let calls = c.finite_differences(
                f,
                t,
                x,
                &self.fy,
                scale,
                &mut self.coloured,
                &mut self.shifted,
                &mut self.k1,
            );
            for i in 0..n {
                for j in 0..n {
                    self.jac[(i, j)] = self.coloured[i * n + j];
                }
            }
            stats.rhs_evaluations += calls + 1;
        } else {
            self.shifted.copy_from_slice(x);
            for j in 0..n {
                let d = FD_EPS * x[j].abs().max(scale[j]);
                self.shifted[j] = x[j] + d;
                f(t, &self.shifted, &mut self.k1);
                self.shifted[j] = x[j];
                for i in 0..n {
                    self.jac[(i, j)] = (self.k1[i] - self.fy[i]) / d;
                }
            }
            stats.rhs_evaluations += n + 1;
        }
        stats.jacobian_evaluations += 1;
        let mut m = &self.jac * (-h * GAMMA);
        for i in 0..n {
            m[(i, i)] += 1.0;
        }
        if m.iter().any(|v| !v.is_finite()) {
            return Err(SolverError::NonFinite { t });
        }
        self.lu = Some(m.lu());
        stats.factorisations += 1;
        Ok(())
    }

    /// Solve y = base + h gamma f(t, y) by simplified Newton from the current y; when
    /// [`MAX_NEWTON`] iterations do not converge, once more from where they got with the
    /// Jacobian formed there (a kink of the right-hand side, a valve land crossing, lies
    /// between the step's start and its solution), then give up.
    #[allow(clippy::too_many_arguments)]
    fn solve_stage<F>(
        &mut self,
        f: &F,
        t: f64,
        h: f64,
        tol: &Tolerances,
        scale: &[f64],
        stats: &mut SolverStats,
    ) -> Result<(), SolverError>
    where
        F: Fn(f64, &[f64], &mut [f64]),
    {
        for attempt in 0..=NEWTON_REFRESHES {
            if attempt > 0 {
                let y = self.y.clone();
                self.factorise(f, t, &y, h, scale, stats)?;
            }
            if self.newton(f, t, h, tol, stats)? {
                return Ok(());
            }
        }
        Err(SolverError::Failed {
            t,
            message: format!(
                "fixed step: Newton did not converge in {MAX_NEWTON} iterations with {} \
                 Jacobian refreshes at h = {h:e} s; take a smaller solver.fixed_step",
                NEWTON_REFRESHES
            ),
        })
    }

    /// Up to [`MAX_NEWTON`] simplified Newton iterations; whether they converged.
    fn newton<F>(
        &mut self,
        f: &F,
        t: f64,
        h: f64,
        tol: &Tolerances,
        stats: &mut SolverStats,
    ) -> Result<bool, SolverError>
    where
        F: Fn(f64, &[f64], &mut [f64]),
    {
        let n = self.y.len();
        let lu = self.lu.as_ref().expect("factorised before the first stage");
        for _ in 0..MAX_NEWTON {
            f(t, &self.y, &mut self.fy);
            stats.rhs_evaluations += 1;
            for i in 0..n {
                self.residual[i] = self.base[i] + h * GAMMA * self.fy[i] - self.y[i];
            }
            if !lu.solve_mut(&mut self.residual) {
                return Err(SolverError::Failed {
                    t,
                    message: "fixed step: singular Newton matrix".into(),
                });
            }
            // weighted RMS of the correction, the adaptive solver's error norm
            let mut norm = 0.0;
            for i in 0..n {
                self.y[i] += self.residual[i];
                let w = tol.atol[i] + tol.rtol * self.y[i].abs();
                norm += (self.residual[i] / w).powi(2);
            }
            let norm = (norm / n as f64).sqrt();
            if !norm.is_finite() {
                return Err(SolverError::NonFinite { t });
            }
            if norm <= NEWTON_TOLERANCE {
                return Ok(true);
            }
        }
        Ok(false)
    }
}

/// Jacobian refreshes a stage may take when simplified Newton stalls: bounded, so the
/// worst-case cost of a step is known (docs/realtime.md gives how often it happens).
pub const NEWTON_REFRESHES: usize = 1;

/// Newton stops when its correction's weighted RMS (weights atol + rtol |y|, those of the
/// adaptive solver) is below this. Measured: 0.1 and 10 give the same positions and
/// pressures as 1 to 0.01 um and 0.001 bar over 3 s of the moves, the fixed step's own
/// error being far larger; 1 is the usual "within tolerance".
const NEWTON_TOLERANCE: f64 = 1.0;

#[cfg(test)]
mod tests {
    use super::*;

    fn tol(n: usize) -> Tolerances {
        Tolerances {
            rtol: 1e-6,
            atol: vec![1e-9; n],
            fixed_step: 0.0,
        }
    }

    /// x1' = -1e5 (x1 - cos t), x2' = x1: x2(1), which is sin 1 up to O(1e-5).
    fn stiff(h: f64) -> f64 {
        let f = |t: f64, x: &[f64], dx: &mut [f64]| {
            dx[0] = -1e5 * (x[0] - t.cos());
            dx[1] = x[0];
        };
        let mut x = [1.0, 0.0];
        let mut stats = SolverStats::default();
        integrate(&f, &mut x, 0.0, 1.0, h, &tol(2), &[1.0, 1.0], &mut stats).unwrap();
        assert_eq!(stats.steps, (1.0 / h).round() as usize);
        x[1]
    }

    #[test]
    fn stiff_system_is_stable_at_steps_far_above_its_time_constant_and_second_order() {
        // h lambda = -1e3 and -5e2: an explicit method would explode
        let fine = stiff(1e-4);
        assert!((fine - 1f64.sin()).abs() < 1e-4, "{fine}");
        let e1 = (stiff(1e-2) - fine).abs();
        let e2 = (stiff(5e-3) - fine).abs();
        assert!(e1 < 1e-4, "{e1}");
        // second order: halving the step divides the error by about 4
        assert!(e1 / e2 > 3.0 && e1 / e2 < 5.0, "{e1} {e2}");
    }

    #[test]
    fn newton_failure_within_the_bound_is_an_error() {
        // x' = -1e4 x^5 from x = 10 in one step of 1 s: the Jacobian at the start is
        // far from the one at the solution, and simplified Newton cannot get there
        let f = |_t: f64, x: &[f64], dx: &mut [f64]| dx[0] = -1e4 * x[0].powi(5);
        let mut x = [10.0];
        let r = integrate(
            &f,
            &mut x,
            0.0,
            1.0,
            1.0,
            &tol(1),
            &[1.0],
            &mut SolverStats::default(),
        );
        match r {
            Err(SolverError::Failed { message, .. }) => {
                assert!(message.contains("Newton"), "{message}")
            }
            other => panic!("expected a Newton failure, got {other:?} with x = {x:?}"),
        }
    }

    #[test]
    fn an_interval_a_rounding_error_longer_than_whole_steps_takes_no_extra_step() {
        let f = |_t: f64, x: &[f64], dx: &mut [f64]| dx[0] = -x[0];
        let mut x = [1.0];
        let mut stats = SolverStats::default();
        // 0.003 - 0.002 is 1e-3 plus a rounding error
        integrate(&f, &mut x, 0.002, 0.003, 1e-3, &tol(1), &[1.0], &mut stats).unwrap();
        assert_eq!(stats.steps, 1);
        integrate(
            &f,
            &mut x,
            0.003,
            0.003 + 1e-15,
            1e-3,
            &tol(1),
            &[1.0],
            &mut stats,
        )
        .unwrap();
        assert_eq!(stats.steps, 2);
        assert!((x[0] - (-1e-3f64).exp()).abs() < 1e-9, "{x:?}");
    }

    #[test]
    fn a_step_too_small_for_the_interval_is_refused_not_looped_on() {
        let f = |_t: f64, x: &[f64], dx: &mut [f64]| dx[0] = -x[0];
        let mut x = [1.0];
        let mut stats = SolverStats::default();
        for h in [5e-324, 1e-12] {
            let r = integrate(&f, &mut x, 0.0, 1e-3, h, &tol(1), &[1.0], &mut stats);
            match r {
                Err(SolverError::Failed { message, .. }) => {
                    assert!(message.contains("solver.fixed_step"), "{message}")
                }
                other => panic!("expected a refusal, got {other:?}"),
            }
        }
        assert_eq!(stats.steps, 0);
        assert_eq!(x, [1.0]);
        // the largest interval the bound allows still runs
        integrate(&f, &mut x, 0.0, 1.0, 1e-4, &tol(1), &[1.0], &mut stats).unwrap();
        assert_eq!(stats.steps, 10_000);
    }
}
