//! Our own adaptive stiff integrator: ESDIRK3(2)4L[2]SA with simplified Newton, Jacobian
//! and LU reused across steps and across communication intervals, and an error estimate
//! filtered through the LU it already holds.
//!
//! Why not diffsol's ESDIRK34 with the same tableau: measured on the thesis's +-10 mm
//! moves under 1 kHz P control (docs/bench.json before this module, rtol 1e-6), diffsol
//! took 14 steps, 2 finite-difference Jacobians (23 right-hand sides each) and 6.7 LU per
//! 1 ms interval (11 simulated s per CPU s). Two causes. (1) Its error estimate is the raw
//! embedded difference: after each input jump the fast (~10 us) manifold and valve modes
//! relax, the raw estimate sees that transient and forces tiny steps, although an
//! L-stable stiffly accurate method damps it correctly. scipy's Radau filters its
//! estimate through (I - h gamma J)^-1 (Hairer & Wanner, Solving ODEs II, IV.8, (8.20);
//! Shampine 1982) and takes ~2 steps per interval at the same accuracy. diffsol offers no
//! such filter. (2) diffsol's solver is rebuilt every interval, so its Jacobian and LU
//! are thrown away at each communication point, and it cannot be carried bit-exactly
//! through an FMU state.
//!
//! Method: Kennedy & Carpenter's ESDIRK3(2)4L[2]SA (NASA/TM-2016-219173, section 5.2.1;
//! the tableau diffsol ships as `esdirk34`): 4 stages, the first explicit, three implicit
//! with the same diagonal gamma, order 3 with an embedded order-2 solution, L-stable and
//! stiffly accurate (the last stage is the new state, first stage of the next step).
//!
//! Rules (Hairer & Wanner IV.8): each implicit stage is solved by simplified Newton with
//! the matrix I - h' gamma J, J and h' from earlier steps; Newton stops when
//! eta ||dz|| <= [`NEWTON_KAPPA`] (eta = theta / (1 - theta), theta the contraction
//! rate); a new Jacobian is formed at the next step's start when Newton contracted more
//! slowly than [`THETA_REFRESH`] or failed with an old J; the LU is refactored only when
//! h gamma moves by more than [`REFACTOR_RATIO`] or J changes. Steps of an interval are
//! equal (the remaining span over the fewest steps no longer than the controller's
//! proposal), so a steady step size keeps one LU for many intervals.
//!
//! Everything that changes results lives in [`Memory`] (carried in the bench's
//! `SimState`, so an FMU state replays bit for bit); [`Workspace`] holds buffers and the
//! LU, which is a function of (Memory::jacobian, Memory::newton_hgamma) and refactored
//! from them whenever it does not match.

use super::dense_lu::DenseLu;
use super::esdirk_tableau::{A, C, D, GAMMA};
use super::jacobian::{Colouring, ExactJacobian};
use super::{SolverError, SolverStats, Tolerances};

/// Which earlier stage each implicit stage starts Newton from: the one nearest in time,
/// whose derivative is known, so the first Newton iteration costs a solve and no
/// right-hand side (stage 2 from x0 at c = 0, stages 3 and 4 from stage 2 at c = 0.87).
const START: [usize; 4] = [0, 0, 1, 1];

/// Simplified Newton stops when eta ||dz|| is below this (norm weighted by atol + rtol |x|).
/// Hairer & Wanner advise 0.01-0.1; larger saves iterations. Measured on the moves
/// (hbench bench, 3 s, static / second-order / two-stage valves, simulated s per CPU s,
/// max |y - y(diffsol, rtol 1e-9)|): 0.01 gave 12.4 / 28.3 / 5.4 at 0.008 / 0.008 /
/// 0.011 um; 0.05 gave 12.8 / 30.6 / 6.5 at 0.007 / 0.008 / 0.012 um; 0.2 gave 15.7 /
/// 35.5 / 7.6 at 0.008 / 0.008 / 0.012 um (the error estimate, not Newton, sets the
/// accuracy: the iterations' remainder stays a fifth of the tolerance). But the moves do
/// not decide it: on the gap workflow's closed-loop sweep of a bench with the manifold's
/// passages (2.5 s, losses 3.4 times the built-in ones), 0.2 and 0.05 both left the loop
/// near 2.28 s on another branch (P1 cavitating, y drifting 2.7 mm, 1500 noise levels
/// of pressure away from diffsol's BDF and ESDIRK34, which agree with each other within
/// 0.85), while 0.01 stays within 1.2 pressure noise levels of BDF, at 1.69 CPU s
/// against 1.30 (measured). The lower end of Hairer's range, then.
const NEWTON_KAPPA: f64 = 0.01;
/// Newton iterations per stage before the step is retried (new J, or half the step).
const MAX_NEWTON: usize = 7;
/// A contraction rate above this at an accepted step asks for a new Jacobian at the next.
/// Measured with NEWTON_KAPPA 0.05 on the static-valve moves: 0.1 and 0.3 take the same
/// steps; 0.3 forms 20 Jacobians instead of 316 in 3 s but spends more right-hand sides
/// in slower Newton iterations (145k against 107k) and is no faster; 0 (a Jacobian every
/// step) costs 2 000 Jacobians per second.
const THETA_REFRESH: f64 = 0.1;
/// The LU of I - h gamma J is refactored when h gamma differs from the one it was formed
/// with by more than this fraction (simplified Newton tolerates a moderate mismatch).
const REFACTOR_RATIO: f64 = 0.2;
/// Step controller (Hairer & Wanner II.4): safety factor and bounds of the step ratio.
/// An I controller: Gustafsson's PI controller (Hairer & Wanner IV.8 (8.21)) took 41.9 k
/// steps instead of 33.7 k over 3 s of the static-valve moves and was no faster, and
/// Radau5's rule of keeping a step that would grow by less than 1.2 saved no LU
/// (13.4 k against 13.3 k: the refactorisations follow the shrinking steps).
const SAFETY: f64 = 0.9;
const MAX_GROWTH: f64 = 5.0;
const MAX_SHRINK: f64 = 0.2;
/// Shortest step before the integration gives up: diffsol's own minimum, so both
/// engines fail on the same problems.
const MIN_STEP: f64 = super::DIFFSOL_MIN_STEP;
/// Steps may come this fraction over the proposal when an interval is cut into equal
/// steps: a rounding error must not add one.
const STEP_ROUNDING: f64 = 1e-9;
/// Newton failures with a Jacobian formed at the step's start, within one interval,
/// before the interval is handed back as [`SolverError::Stalled`]: each one halves the
/// step, so 20 of them mean a step a million times shorter than proposed. Found by the
/// fuzzer (bench_closed_loop: 0.1 kg mass, 0.16 L dead volume, viscous 1911 N s/m, 10 V
/// into the end stop after 1 ns and 1 us intervals): simplified Newton kept failing at
/// the end-stop contact and the integrator crawled through 8.6 million steps (20 s of
/// CPU); diffsol's ESDIRK34, which forms its Newton matrix differently, passes the same
/// intervals in about a thousand steps ([`super::advance`] hands it the interval).
pub const MAX_FRESH_FAILURES: usize = 20;

/// What the integrator carries from one interval to the next and what its results depend
/// on: part of the bench's `SimState`, validated by [`Memory::validate`].
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Memory {
    /// The Jacobian of the Newton matrix, row-major n x n; empty before the first step.
    #[serde(default)]
    pub jacobian: Vec<f64>,
    /// h gamma of the Newton matrix I - h gamma J in use (0 before the first step).
    #[serde(default)]
    pub newton_hgamma: f64,
    /// Newton's last measured eta = theta / (1 - theta), the first iteration's guess.
    #[serde(default)]
    pub newton_eta: f64,
    /// Newton contracted slowly: form a new Jacobian at the next step's start.
    #[serde(default)]
    pub refresh_jacobian: bool,
}

impl Memory {
    /// A memory restored from outside must be one this integrator could have left.
    pub fn validate(&self, n: usize) -> Result<(), String> {
        if !self.jacobian.is_empty() && self.jacobian.len() != n * n {
            return Err(format!(
                "integrator memory: Jacobian of {} values for {n} states",
                self.jacobian.len()
            ));
        }
        if self.jacobian.iter().any(|v| !v.is_finite()) {
            return Err("integrator memory: non-finite Jacobian".into());
        }
        let h_ok = self.newton_hgamma.is_finite()
            && (self.newton_hgamma > 0.0
                || (self.newton_hgamma == 0.0 && self.jacobian.is_empty()));
        if !h_ok {
            return Err(format!(
                "integrator memory: invalid Newton h gamma {}",
                self.newton_hgamma
            ));
        }
        if !(self.newton_eta.is_finite() && self.newton_eta >= 0.0) {
            return Err(format!(
                "integrator memory: invalid Newton rate {}",
                self.newton_eta
            ));
        }
        Ok(())
    }
}

/// Buffers and the factorised Newton matrix: allocated once per model, nothing in the
/// step loop allocates.
#[derive(Debug)]
pub struct Workspace {
    n: usize,
    /// f does not depend on t (the bench, its inputs held over an interval): Newton may
    /// then start a stage from an earlier stage with that stage's derivative, no call.
    autonomous: bool,
    colouring: Colouring,
    lu: DenseLu,
    /// Whether `lu` holds a factorisation.
    factorised: bool,
    /// The (J, h gamma) the LU was formed from: it is refactored when the memory differs.
    lu_jacobian: Vec<f64>,
    lu_hgamma: f64,
    x0: Vec<f64>,
    k: [Vec<f64>; 4],
    z: [Vec<f64>; 4],
    base: Vec<f64>,
    fz: Vec<f64>,
    delta: Vec<f64>,
    weights: Vec<f64>,
    shifted: Vec<f64>,
    fh: Vec<f64>,
}

impl Workspace {
    /// A workspace for n states whose finite-difference Jacobian uses `colouring`.
    pub fn new(colouring: Colouring) -> Workspace {
        let n = colouring.n();
        let v = || vec![0.0; n];
        Workspace {
            n,
            autonomous: false,
            colouring,
            lu: DenseLu::new(n),
            factorised: false,
            lu_jacobian: Vec::with_capacity(n * n),
            lu_hgamma: 0.0,
            x0: v(),
            k: [v(), v(), v(), v()],
            z: [v(), v(), v(), v()],
            base: v(),
            fz: v(),
            delta: v(),
            weights: v(),
            shifted: v(),
            fh: v(),
        }
    }

    /// Declare f independent of t (see the field).
    pub fn autonomous(mut self) -> Workspace {
        self.autonomous = true;
        self
    }

    /// The colouring of the finite-difference Jacobian.
    pub fn colouring(&self) -> &Colouring {
        &self.colouring
    }

    /// Factorise I - hg J from the memory, and remember what from.
    fn factorise(
        &mut self,
        mem: &Memory,
        t: f64,
        stats: &mut SolverStats,
    ) -> Result<(), SolverError> {
        let n = self.n;
        let hg = mem.newton_hgamma;
        let m = self.lu.matrix_mut();
        for (mij, jij) in m.iter_mut().zip(&mem.jacobian) {
            *mij = -hg * jij;
        }
        (0..n).for_each(|i| m[i * n + i] += 1.0);
        self.lu_jacobian.clear();
        self.lu_jacobian.extend_from_slice(&mem.jacobian);
        self.lu_hgamma = hg;
        stats.factorisations += 1;
        self.factorised = self.lu.factorise();
        if !self.factorised {
            return Err(SolverError::Failed {
                t,
                message: format!("singular Newton matrix I - h gamma J (h gamma = {hg:e} s)"),
            });
        }
        Ok(())
    }

    /// Solve (I - h' gamma J) delta = delta in place.
    fn solve(&mut self) {
        self.lu.solve(&mut self.delta);
    }

    /// Weighted RMS of `delta` (weights already inverted).
    fn delta_norm(&self) -> f64 {
        let s: f64 = self
            .delta
            .iter()
            .zip(&self.weights)
            .map(|(d, w)| (d * w) * (d * w))
            .sum();
        (s / self.n as f64).sqrt()
    }
}

/// Why one step attempt did not give a new state.
enum Attempt {
    /// Accepted or not by the error norm; the largest Newton contraction rate seen.
    Done { error: f64, theta: f64 },
    /// Newton diverged, was too slow, or met a non-finite right-hand side.
    NewtonFailed,
}

/// Integrate dx/dt = f(t, x) from t0 to t1 (t1 > t0, checked by the caller), `x` in and
/// out. `step` is the proposed step size, carried in and out; `mem` what else the
/// integrator carries. `jac`, when given, is the exact Jacobian; otherwise the workspace's
/// coloured finite differences with the state scales `scale`.
#[allow(clippy::too_many_arguments)]
pub fn integrate<F>(
    f: &F,
    jac: Option<ExactJacobian>,
    x: &mut [f64],
    t0: f64,
    t1: f64,
    tol: &Tolerances,
    scale: &[f64],
    step: &mut Option<f64>,
    mem: &mut Memory,
    ws: &mut Workspace,
    stats: &mut SolverStats,
) -> Result<(), SolverError>
where
    F: Fn(f64, &[f64], &mut [f64]) + ?Sized,
{
    let n = ws.n;
    if x.len() != n || scale.len() != n || tol.atol.len() != n {
        return Err(SolverError::Failed {
            t: t0,
            message: format!("integrator set up for {n} states, given {}", x.len()),
        });
    }
    mem.validate(n)
        .map_err(|message| SolverError::Failed { t: t0, message })?;
    if mem.jacobian.is_empty() {
        mem.jacobian = vec![0.0; n * n];
        mem.refresh_jacobian = true;
        // no rate measured yet: the first stage must iterate until it measures one
        mem.newton_eta = 1.0;
    }
    // the first derivative of the interval: the inputs jumped at t0
    f(t0, x, &mut ws.k[0]);
    stats.rhs_evaluations += 1;
    if ws.k[0].iter().any(|v| !v.is_finite()) {
        return Err(SolverError::NonFinite { t: t0 });
    }
    let mut proposal = match *step {
        Some(h) if h.is_finite() && h > 0.0 => h,
        _ => initial_step(x, &ws.k[0], tol),
    };
    let mut t = t0;
    // J formed at this step's start (a Newton failure then halves the step instead)
    let mut fresh = false;
    let mut rejected = false;
    let mut fresh_failures = 0usize;
    // the LU in the workspace is the one of the memory's (J, h gamma)? A restored state
    // or another model's run leaves a different one
    let mut lu_valid =
        ws.factorised && ws.lu_hgamma == mem.newton_hgamma && ws.lu_jacobian == mem.jacobian;
    while t < t1 {
        let remaining = t1 - t;
        let count = (remaining / proposal - STEP_ROUNDING).ceil().max(1.0);
        let last = count <= 1.0;
        let h = if last { remaining } else { remaining / count };
        if h < MIN_STEP {
            return Err(SolverError::Failed {
                t,
                message: format!("step size {h:e} s is too small"),
            });
        }
        if mem.refresh_jacobian && !fresh {
            form_jacobian(f, jac, t, x, scale, mem, ws, stats)?;
            fresh = true;
            lu_valid = false;
        }
        let hg = h * GAMMA;
        if mem.newton_hgamma == 0.0 || (hg / mem.newton_hgamma - 1.0).abs() > REFACTOR_RATIO {
            mem.newton_hgamma = hg;
            lu_valid = false;
        }
        if !lu_valid {
            ws.factorise(mem, t, stats)?;
            lu_valid = true;
        }
        match attempt(f, t, h, x, tol, mem, ws, stats) {
            Attempt::Done { error, theta } if error <= 1.0 => {
                x.copy_from_slice(&ws.z[3]);
                // stiffly accurate: the last stage's derivative is the next step's first
                let (first, rest) = ws.k.split_at_mut(1);
                first[0].copy_from_slice(&rest[2]);
                t = if last { t1 } else { t + h };
                stats.steps += 1;
                if x.iter().any(|v| !v.is_finite()) {
                    return Err(SolverError::NonFinite { t });
                }
                let growth = if rejected { 1.0 } else { MAX_GROWTH };
                proposal = h * step_ratio(error).min(growth);
                rejected = false;
                fresh = false;
                if theta > THETA_REFRESH {
                    mem.refresh_jacobian = true;
                }
            }
            Attempt::Done { error, .. } => {
                proposal = h * step_ratio(error).min(1.0);
                rejected = true;
            }
            Attempt::NewtonFailed => {
                if fresh {
                    fresh_failures += 1;
                    if fresh_failures > MAX_FRESH_FAILURES {
                        // the next attempt starts from a new Jacobian
                        mem.refresh_jacobian = true;
                        return Err(SolverError::Stalled { t });
                    }
                    proposal = 0.5 * h;
                    rejected = true;
                } else {
                    mem.refresh_jacobian = true;
                }
            }
        }
    }
    // the last stage's derivative came from its equation, not from f: a state where f
    // is not finite (outside the model's domain) would pass unseen into the next interval
    f(t1, x, &mut ws.fz);
    stats.rhs_evaluations += 1;
    if ws.fz.iter().any(|v| !v.is_finite()) {
        return Err(SolverError::NonFinite { t: t1 });
    }
    *step = Some(proposal);
    Ok(())
}

/// Factor by which the next step may grow or must shrink for the error norm `error` of
/// an order-2 estimate (local error ~ h^3).
fn step_ratio(error: f64) -> f64 {
    if error <= 0.0 {
        return MAX_GROWTH;
    }
    (SAFETY * error.powf(-1.0 / 3.0)).clamp(MAX_SHRINK, MAX_GROWTH)
}

/// First step when none is carried: 1 % of the time the state takes to change by its own
/// weighted size at the initial rate (Hairer & Wanner II.4, the first part of their
/// starting-step algorithm), at most 1 ms of the interval's kind.
fn initial_step(x: &[f64], fx: &[f64], tol: &Tolerances) -> f64 {
    let norm = |v: &[f64]| {
        let s: f64 = v
            .iter()
            .zip(x)
            .zip(&tol.atol)
            .map(|((vi, xi), a)| (vi / (a + tol.rtol * xi.abs())).powi(2))
            .sum();
        (s / x.len() as f64).sqrt()
    };
    let (d0, d1) = (norm(x), norm(fx));
    if d0 < 1e-5 || d1 < 1e-5 {
        1e-6
    } else {
        0.01 * d0 / d1
    }
}

/// Form J at (t, x): the exact hook, else coloured differences around a fresh f(t, x)
/// (the carried first-stage derivative holds Newton's residual / h gamma, too coarse a
/// base for differences).
#[allow(clippy::too_many_arguments)]
fn form_jacobian<F>(
    f: &F,
    jac: Option<ExactJacobian>,
    t: f64,
    x: &[f64],
    scale: &[f64],
    mem: &mut Memory,
    ws: &mut Workspace,
    stats: &mut SolverStats,
) -> Result<(), SolverError>
where
    F: Fn(f64, &[f64], &mut [f64]) + ?Sized,
{
    match jac {
        Some(exact) => exact(t, x, &mut mem.jacobian),
        None => {
            f(t, x, &mut ws.fz);
            let calls = ws.colouring.finite_differences(
                f,
                t,
                x,
                &ws.fz,
                scale,
                &mut mem.jacobian,
                &mut ws.shifted,
                &mut ws.fh,
            );
            stats.rhs_evaluations += calls + 1;
        }
    }
    stats.jacobian_evaluations += 1;
    mem.refresh_jacobian = false;
    if mem.jacobian.iter().any(|v| !v.is_finite()) {
        return Err(SolverError::NonFinite { t });
    }
    Ok(())
}

/// One step of size h from (t, x) with k[0] = f(t, x): the three implicit stages by
/// simplified Newton, then the filtered error estimate. The new state is z[3].
// index loops over several parallel arrays read clearer than zipped iterators here
#[allow(clippy::too_many_arguments, clippy::needless_range_loop)]
fn attempt<F>(
    f: &F,
    t: f64,
    h: f64,
    x: &[f64],
    tol: &Tolerances,
    mem: &mut Memory,
    ws: &mut Workspace,
    stats: &mut SolverStats,
) -> Attempt
where
    F: Fn(f64, &[f64], &mut [f64]) + ?Sized,
{
    let n = ws.n;
    let hg = h * GAMMA;
    for i in 0..n {
        ws.weights[i] = 1.0 / (tol.atol[i] + tol.rtol * x[i].abs());
    }
    ws.x0.copy_from_slice(x);
    ws.z[0].copy_from_slice(x);
    // Hairer & Wanner IV.8: the first iteration's rate from the last measured one
    let mut eta = mem.newton_eta.max(f64::EPSILON).powf(0.8);
    mem.newton_eta = eta;
    let mut theta_max = 0.0f64;
    for s in 1..4 {
        // base = x0 + h sum_{j<s} a_sj k_j
        for i in 0..n {
            let mut acc = 0.0;
            for j in 0..s {
                acc += A[s][j] * ws.k[j][i];
            }
            ws.base[i] = ws.x0[i] + h * acc;
        }
        let from = START[s];
        let (zs, zfrom) = split_pair(&mut ws.z, s, from);
        zs.copy_from_slice(zfrom);
        ws.fz.copy_from_slice(&ws.k[from]);
        let mut previous = 0.0;
        let mut converged = false;
        for it in 0..MAX_NEWTON {
            let ts = t + C[s] * h;
            if it > 0 || !ws.autonomous {
                f(ts, &ws.z[s], &mut ws.fz);
                stats.rhs_evaluations += 1;
                if ws.fz.iter().any(|v| !v.is_finite()) {
                    return Attempt::NewtonFailed;
                }
            }
            for i in 0..n {
                ws.delta[i] = ws.base[i] + hg * ws.fz[i] - ws.z[s][i];
            }
            ws.solve();
            for i in 0..n {
                ws.z[s][i] += ws.delta[i];
            }
            let norm = ws.delta_norm();
            if !norm.is_finite() {
                return Attempt::NewtonFailed;
            }
            let mut theta = 0.0;
            if it > 0 {
                theta = norm / previous;
                theta_max = theta_max.max(theta);
                if theta >= 1.0 {
                    return Attempt::NewtonFailed;
                }
                eta = theta / (1.0 - theta);
                mem.newton_eta = eta;
            }
            if eta * norm <= NEWTON_KAPPA || norm == 0.0 {
                converged = true;
                break;
            }
            // the iterations left cannot reach the tolerance at this rate
            let left = (MAX_NEWTON - 1 - it) as i32;
            if it > 0 && theta.powi(left) / (1.0 - theta) * norm > NEWTON_KAPPA {
                return Attempt::NewtonFailed;
            }
            previous = norm;
        }
        if !converged {
            return Attempt::NewtonFailed;
        }
        // k_s from the stage equation z = base + h gamma k: no right-hand side call
        for i in 0..n {
            ws.k[s][i] = (ws.z[s][i] - ws.base[i]) / hg;
        }
    }
    // embedded estimate h sum d_i k_i, filtered through (I - h gamma J)^-1
    for i in 0..n {
        let mut acc = 0.0;
        for j in 0..4 {
            acc += D[j] * ws.k[j][i];
        }
        ws.delta[i] = h * acc;
    }
    ws.solve();
    for i in 0..n {
        ws.weights[i] = 1.0 / (tol.atol[i] + tol.rtol * x[i].abs().max(ws.z[3][i].abs()));
    }
    let error = ws.delta_norm();
    if !error.is_finite() {
        return Attempt::NewtonFailed;
    }
    Attempt::Done {
        error,
        theta: theta_max,
    }
}

/// Mutable stage `a` and shared stage `b` (b < a) of the stage array.
fn split_pair(z: &mut [Vec<f64>; 4], a: usize, b: usize) -> (&mut Vec<f64>, &Vec<f64>) {
    let (lo, hi) = z.split_at_mut(a);
    (&mut hi[0], &lo[b])
}
