//! Jacobians for the Newton matrices: coloured finite differences over a probed sparsity
//! pattern (Curtis, Powell & Reid 1974), the fallback until each model supplies an exact
//! Jacobian through the hook [`ExactJacobian`].
//!
//! The bench couples each state to a few others (a manifold node to its passages, a
//! passage to its two ends, a chamber to the piston): columns that share no row can be
//! perturbed together, so a Jacobian costs one right-hand side per colour instead of one
//! per state. The pattern is found once per model by perturbing every state at a few
//! valid states and OR-ing what changes; a dependency the probes miss (a kink where a
//! derivative is zero at every probe) only slows simplified Newton down, it never changes
//! what Newton converges to.

use super::FD_EPS;

/// A right-hand side f(t, x, dx) behind a reference, one compiled body for every caller.
pub type DynRhs<'a> = &'a dyn Fn(f64, &[f64], &mut [f64]);

/// An exact Jacobian: `jac(t, x, J)` writes d f_i / d x_j into `J[i * n + j]` (row-major).
pub type ExactJacobian<'a> = &'a dyn Fn(f64, &[f64], &mut [f64]);

/// Which entries of the Jacobian may be non-zero, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Pattern {
    n: usize,
    nonzero: Vec<bool>,
}

/// Relative perturbation of the probes: large enough that every dependency changes the
/// right-hand side beyond rounding (FD_EPS-sized steps can vanish against a large f_i),
/// small enough to stay on the same side of the model's kinks most of the time.
const PROBE_STEP: f64 = 1e-4;

impl Pattern {
    /// Only the diagonal (every Newton matrix I - h gamma J has it).
    pub fn diagonal(n: usize) -> Pattern {
        let mut nonzero = vec![false; n * n];
        (0..n).for_each(|i| nonzero[i * n + i] = true);
        Pattern { n, nonzero }
    }

    /// Every entry: what a model without a known pattern gets.
    pub fn dense(n: usize) -> Pattern {
        Pattern {
            n,
            nonzero: vec![true; n * n],
        }
    }

    /// Add the dependencies seen at state `x`: perturb each state by [`PROBE_STEP`] of
    /// its magnitude (at least of `scale`) and mark the derivatives that change. A state
    /// where f is not finite teaches nothing and is skipped; a non-finite perturbed
    /// derivative counts as a dependency.
    pub fn probe<F>(&mut self, f: &F, x: &[f64], scale: &[f64])
    where
        F: Fn(f64, &[f64], &mut [f64]) + ?Sized,
    {
        let n = self.n;
        let mut f0 = vec![0.0; n];
        let mut f1 = vec![0.0; n];
        f(0.0, x, &mut f0);
        if f0.iter().any(|v| !v.is_finite()) {
            return;
        }
        let mut shifted = x.to_vec();
        for j in 0..n {
            shifted[j] = x[j] + PROBE_STEP * x[j].abs().max(scale[j]);
            f(0.0, &shifted, &mut f1);
            shifted[j] = x[j];
            for i in 0..n {
                if f1[i] != f0[i] {
                    self.nonzero[i * n + j] = true;
                }
            }
        }
    }

    pub fn count(&self) -> usize {
        self.nonzero.iter().filter(|b| **b).count()
    }
}

/// Columns grouped so that no two columns of a group share a non-zero row.
#[derive(Debug, Clone, PartialEq)]
pub struct Colouring {
    n: usize,
    /// The columns of each colour.
    groups: Vec<Vec<usize>>,
    /// The rows where each column may be non-zero.
    rows: Vec<Vec<usize>>,
}

impl Colouring {
    /// Greedy colouring, columns taken by decreasing count of non-zeros (Welsh-Powell):
    /// each takes the first colour none of whose columns shares a row with it.
    pub fn greedy(p: &Pattern) -> Colouring {
        let n = p.n;
        let rows: Vec<Vec<usize>> = (0..n)
            .map(|j| (0..n).filter(|&i| p.nonzero[i * n + j]).collect())
            .collect();
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by_key(|&j| std::cmp::Reverse(rows[j].len()));
        let mut groups: Vec<Vec<usize>> = Vec::new();
        // rows already taken by each colour
        let mut taken: Vec<Vec<bool>> = Vec::new();
        for j in order {
            let free = taken.iter().position(|t| rows[j].iter().all(|&i| !t[i]));
            let c = free.unwrap_or_else(|| {
                groups.push(Vec::new());
                taken.push(vec![false; n]);
                groups.len() - 1
            });
            groups[c].push(j);
            rows[j].iter().for_each(|&i| taken[c][i] = true);
        }
        groups.iter_mut().for_each(|g| g.sort_unstable());
        Colouring { n, groups, rows }
    }

    /// One colour per column, every row: plain dense differences.
    pub fn dense(n: usize) -> Colouring {
        Colouring::greedy(&Pattern::dense(n))
    }

    pub fn colours(&self) -> usize {
        self.groups.len()
    }

    pub fn n(&self) -> usize {
        self.n
    }

    /// J at (t, x) by one-sided differences, one right-hand side per colour; `fx` is
    /// f(t, x), `shifted` and `fh` are work buffers of length n. Entries outside the
    /// pattern are zero. Returns the right-hand sides it called.
    #[allow(clippy::too_many_arguments)]
    pub fn finite_differences<F>(
        &self,
        f: &F,
        t: f64,
        x: &[f64],
        fx: &[f64],
        scale: &[f64],
        jac: &mut [f64],
        shifted: &mut [f64],
        fh: &mut [f64],
    ) -> usize
    where
        F: Fn(f64, &[f64], &mut [f64]) + ?Sized,
    {
        let n = self.n;
        jac.iter_mut().for_each(|v| *v = 0.0);
        shifted.copy_from_slice(x);
        for group in &self.groups {
            for &j in group {
                shifted[j] = x[j] + FD_EPS * x[j].abs().max(scale[j]);
            }
            f(t, shifted, fh);
            for &j in group {
                // the step as represented, not as intended
                let d = shifted[j] - x[j];
                for &i in &self.rows[j] {
                    jac[i * n + j] = (fh[i] - fx[i]) / d;
                }
                shifted[j] = x[j];
            }
        }
        self.groups.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tridiagonal chain with a dense last row: columns 0, 3, 6, ... share no row
    /// except the last.
    fn chain(_t: f64, x: &[f64], dx: &mut [f64]) {
        let n = x.len();
        for i in 0..n - 1 {
            let left = if i > 0 { x[i - 1] } else { 0.0 };
            let right = x[i + 1];
            dx[i] = -2.0 * x[i] * x[i] + left + 3.0 * right;
        }
        dx[n - 1] = x.iter().sum::<f64>().sin();
    }

    #[test]
    fn probing_finds_the_chain_and_colouring_keeps_columns_apart() {
        let n = 9;
        let mut p = Pattern::diagonal(n);
        let x: Vec<f64> = (0..n).map(|i| 0.3 + 0.1 * i as f64).collect();
        p.probe(&chain, &x, &vec![1.0; n]);
        // 3 per row but the first (2) and the last (dense)
        assert_eq!(p.count(), 2 + 3 * (n - 2) + n);
        let c = Colouring::greedy(&p);
        // the dense last row makes every column collide: n colours
        assert_eq!(c.colours(), n);
        for g in &c.groups {
            for (a, &j) in g.iter().enumerate() {
                for &k in &g[a + 1..] {
                    assert!(c.rows[j].iter().all(|i| !c.rows[k].contains(i)));
                }
            }
        }
        // without the dense row, a tridiagonal matrix needs 3 colours
        let mut tri = Pattern::diagonal(n);
        for i in 0..n - 1 {
            tri.nonzero[i * n + i + 1] = true;
            tri.nonzero[(i + 1) * n + i] = true;
        }
        assert_eq!(Colouring::greedy(&tri).colours(), 3);
    }

    #[test]
    fn coloured_differences_equal_dense_differences_on_a_tridiagonal_system() {
        let n = 12;
        // through one vtable, so that f(x) here and inside the differences run the same
        // machine code (powi's rounding may differ between two inlined copies)
        let f: DynRhs = &|_t, x, dx| {
            for i in 0..n {
                let l = if i > 0 { x[i - 1] } else { 1.0 };
                let r = if i + 1 < n { x[i + 1] } else { 1.0 };
                dx[i] = l * r - x[i] * x[i] * x[i];
            }
        };
        let x: Vec<f64> = (0..n).map(|i| 1.0 + 0.05 * i as f64).collect();
        let scale = vec![1.0; n];
        let mut fx = vec![0.0; n];
        f(0.0, &x, &mut fx);
        let mut p = Pattern::diagonal(n);
        p.probe(f, &x, &scale);
        let coloured = Colouring::greedy(&p);
        assert_eq!(coloured.colours(), 3);
        let (mut s, mut fh) = (vec![0.0; n], vec![0.0; n]);
        let mut jc = vec![0.0; n * n];
        let mut jd = vec![0.0; n * n];
        let calls = coloured.finite_differences(f, 0.0, &x, &fx, &scale, &mut jc, &mut s, &mut fh);
        assert_eq!(calls, 3);
        Colouring::dense(n).finite_differences(f, 0.0, &x, &fx, &scale, &mut jd, &mut s, &mut fh);
        assert_eq!(jc, jd);
        // and both against the analytic derivative
        for i in 0..n {
            let exact = -3.0 * x[i] * x[i];
            assert!((jc[i * n + i] - exact).abs() < 1e-6 * exact.abs(), "{i}");
        }
    }
}
