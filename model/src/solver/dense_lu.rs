//! LU with partial pivoting, in place and row-major, for the Newton matrices: factorised
//! dense, solved sparse.
//!
//! Written here rather than taken from nalgebra because `nalgebra::LU::new` takes its
//! matrix by value and allocates its permutation at every factorisation, while the
//! integrator must not allocate in its step loop (it refactors every few steps when the
//! step size moves). Speed was no reason at first: in the integrator on the static-valve
//! moves both took the same CPU time (0.22 s for 3 simulated s).
//!
//! The solve runs over the factors' nonzeros only. The bench with the manifold's passages
//! (n = 22) has factors with 87 nonzeros of 484 (measured, steps with the passages' losses
//! hidden), and its dense solve took 44 % of a gap analysis's CPU time (perf, the
//! dry-friction record, where the passages' candidates took most). The nonzeros are
//! summed in the groups the dense substitutions used (four running sums by column
//! position, then the tail), so the results are the dense solve's bit for bit: a product
//! with an exact zero left out changes no sum (a unit test compares both).
//! Four running sums because a single one is a chain of dependent additions, whose
//! latency bounded the dense substitutions at n = 22 (perf).

/// The factors of P A = L U of an n x n matrix, L unit lower triangular.
#[derive(Debug, Clone)]
pub struct DenseLu {
    n: usize,
    /// L below the diagonal, U on and above it, row-major.
    a: Vec<f64>,
    /// 1 / U_ii.
    inv_diag: Vec<f64>,
    /// Row exchanged with row k at step k.
    pivots: Vec<usize>,
    /// The nonzeros of L below the diagonal, (column, value), row by row and within a
    /// row by the running sum they go to (`Summed`).
    lower: Summed,
    /// The nonzeros of U above the diagonal, the same way.
    upper: Summed,
}

/// A triangle's nonzeros off the diagonal, each row's in five runs: the four running
/// sums of the dense substitutions (column position q from the row's first column, q mod
/// 4, while q is below the last multiple of four) and the tail, each run in column order.
#[derive(Debug, Clone)]
struct Summed {
    entries: Vec<(usize, f64)>,
    /// Row i's runs start at bounds[5 i .. 5 i + 5] and end at the next one.
    bounds: Vec<usize>,
}

impl Summed {
    fn with_capacity(n: usize) -> Summed {
        Summed {
            entries: Vec::with_capacity(n * n / 2),
            bounds: Vec::with_capacity(5 * n + 1),
        }
    }

    /// Gather the rows of a triangle: row i spans columns `span(i)` of `a`'s row i.
    fn gather(&mut self, a: &[f64], n: usize, span: impl Fn(usize) -> std::ops::Range<usize>) {
        self.entries.clear();
        self.bounds.clear();
        for i in 0..n {
            let cols = span(i);
            let grouped = cols.start + cols.len() / 4 * 4;
            let row = &a[i * n..(i + 1) * n];
            for run in 0..4 {
                self.bounds.push(self.entries.len());
                let first = cols.start + run;
                self.entries.extend(
                    (first..grouped)
                        .step_by(4)
                        .filter(|&j| row[j] != 0.0)
                        .map(|j| (j, row[j])),
                );
            }
            self.bounds.push(self.entries.len());
            self.entries.extend(
                (grouped..cols.end)
                    .filter(|&j| row[j] != 0.0)
                    .map(|j| (j, row[j])),
            );
        }
        self.bounds.push(self.entries.len());
    }

    /// Row i's product with `b`, summed as the dense substitutions summed the whole row:
    /// (s0 + s1) + (s2 + s3) + tail, each sum in column order. A product with an exact
    /// zero left out changes no sum, so the result is theirs bit for bit.
    fn dot(&self, i: usize, b: &[f64]) -> f64 {
        let r = &self.bounds[5 * i..5 * i + 6];
        if r[0] == r[5] {
            // (0 + 0) + (0 + 0) + an empty sum is +0, whatever the sign of the empty sum
            return 0.0;
        }
        let run = |k: usize| {
            self.entries[r[k]..r[k + 1]]
                .iter()
                .fold(0.0, |s, &(j, v)| s + v * b[j])
        };
        let tail: f64 = self.entries[r[4]..r[5]]
            .iter()
            .map(|&(j, v)| v * b[j])
            .sum();
        (run(0) + run(1)) + (run(2) + run(3)) + tail
    }
}

impl DenseLu {
    pub fn new(n: usize) -> DenseLu {
        DenseLu {
            n,
            a: vec![0.0; n * n],
            inv_diag: vec![0.0; n],
            pivots: (0..n).collect(),
            // capacity for dense factors: filling them never allocates
            lower: Summed::with_capacity(n),
            upper: Summed::with_capacity(n),
        }
    }

    /// The matrix to factorise, row-major, to be filled before [`DenseLu::factorise`].
    pub fn matrix_mut(&mut self) -> &mut [f64] {
        &mut self.a
    }

    /// Factorise the matrix in place; false when it is singular (a zero pivot).
    pub fn factorise(&mut self) -> bool {
        let n = self.n;
        let a = &mut self.a;
        for k in 0..n {
            let mut p = k;
            let mut best = a[k * n + k].abs();
            for i in k + 1..n {
                let v = a[i * n + k].abs();
                if v > best {
                    best = v;
                    p = i;
                }
            }
            if best == 0.0 || !best.is_finite() {
                return false;
            }
            self.pivots[k] = p;
            if p != k {
                for j in 0..n {
                    a.swap(k * n + j, p * n + j);
                }
            }
            let inv = 1.0 / a[k * n + k];
            self.inv_diag[k] = inv;
            let (upper, lower) = a.split_at_mut((k + 1) * n);
            let pivot_row = &upper[k * n + k + 1..(k + 1) * n];
            for row in lower.chunks_exact_mut(n) {
                let l = row[k] * inv;
                row[k] = l;
                if l != 0.0 {
                    for (r, u) in row[k + 1..].iter_mut().zip(pivot_row) {
                        *r -= l * u;
                    }
                }
            }
        }
        // the factors' nonzeros off the diagonal, for `solve`
        self.lower.gather(&self.a, n, |i| 0..i);
        self.upper.gather(&self.a, n, |i| i + 1..n);
        true
    }

    /// Solve A x = b in place (b becomes x).
    pub fn solve(&self, b: &mut [f64]) {
        let n = self.n;
        for (k, &p) in self.pivots.iter().enumerate() {
            b.swap(k, p);
        }
        for i in 1..n {
            let s = self.lower.dot(i, b);
            b[i] -= s;
        }
        for i in (0..n).rev() {
            let s = self.upper.dot(i, b);
            b[i] = (b[i] - s) * self.inv_diag[i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_like_nalgebra_and_needs_the_pivoting() {
        let n = 7;
        // a zero leading entry: no LU without row exchanges
        let m = |i: usize, j: usize| {
            if i == 0 && j == 0 {
                0.0
            } else {
                ((i * 13 + j * 7) % 11) as f64 - 5.0 + if i == j { 3.0 } else { 0.0 }
            }
        };
        let mut lu = DenseLu::new(n);
        for i in 0..n {
            for j in 0..n {
                lu.matrix_mut()[i * n + j] = m(i, j);
            }
        }
        assert!(lu.factorise());
        let b: Vec<f64> = (0..n).map(|i| 1.0 + i as f64).collect();
        let mut x = b.clone();
        lu.solve(&mut x);
        let reference = nalgebra::DMatrix::from_fn(n, n, m)
            .lu()
            .solve(&nalgebra::DVector::from_vec(b.clone()))
            .unwrap();
        for i in 0..n {
            assert!(
                (x[i] - reference[i]).abs() < 1e-12,
                "{i}: {} {}",
                x[i],
                reference[i]
            );
            // and the residual itself
            let r: f64 = (0..n).map(|j| m(i, j) * x[j]).sum::<f64>() - b[i];
            assert!(r.abs() < 1e-12, "{r}");
        }
    }

    /// The dense substitutions the sparse solve replaced: every product summed.
    fn dense_solve(lu: &DenseLu, b: &mut [f64]) {
        let n = lu.n;
        let dot = |a: &[f64], b: &[f64]| {
            let mut acc = [0.0f64; 4];
            let (a4, a_rest) = a.split_at(a.len() / 4 * 4);
            let (b4, b_rest) = b.split_at(a4.len());
            for (x, y) in a4.chunks_exact(4).zip(b4.chunks_exact(4)) {
                for k in 0..4 {
                    acc[k] += x[k] * y[k];
                }
            }
            let tail: f64 = a_rest.iter().zip(b_rest).map(|(x, y)| x * y).sum();
            (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
        };
        for (k, &p) in lu.pivots.iter().enumerate() {
            b.swap(k, p);
        }
        for i in 1..n {
            let s = dot(&lu.a[i * n..i * n + i], &b[..i]);
            b[i] -= s;
        }
        for i in (0..n).rev() {
            let s = dot(&lu.a[i * n + i + 1..(i + 1) * n], &b[i + 1..]);
            b[i] = (b[i] - s) * lu.inv_diag[i];
        }
    }

    /// Over the factors' nonzeros the solve gives the dense substitutions' results bit
    /// for bit, on sparse matrices of the bench's sizes (4, 22) and others, one
    /// factorisation reused for several right-hand sides as the integrator does.
    #[test]
    fn the_sparse_solve_is_the_dense_one_bit_for_bit() {
        // a small linear congruential stream: the test needs no statistical quality
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for &(n, density) in &[(4, 0.5), (7, 0.3), (22, 0.15), (22, 0.6), (30, 0.1)] {
            for _ in 0..20 {
                let mut lu = DenseLu::new(n);
                for i in 0..n {
                    for j in 0..n {
                        let v = if i == j {
                            1.0 + 10.0 * next()
                        } else if next() < density {
                            1e3 * (next() - 0.5)
                        } else {
                            0.0
                        };
                        lu.matrix_mut()[i * n + j] = v;
                    }
                }
                assert!(lu.factorise());
                for _ in 0..5 {
                    let b: Vec<f64> = (0..n).map(|_| 1e6 * (next() - 0.5)).collect();
                    let (mut sparse, mut dense) = (b.clone(), b);
                    lu.solve(&mut sparse);
                    dense_solve(&lu, &mut dense);
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&sparse), bits(&dense), "n = {n}");
                }
            }
        }
    }

    #[test]
    fn a_singular_matrix_is_refused() {
        let mut lu = DenseLu::new(2);
        lu.matrix_mut().copy_from_slice(&[1.0, 2.0, 2.0, 4.0]);
        assert!(!lu.factorise());
    }
}
