//! Dense LU with partial pivoting, in place and row-major, for the Newton matrices.
//!
//! Written here rather than taken from nalgebra because `nalgebra::LU::new` takes its
//! matrix by value and allocates its permutation at every factorisation, while the
//! integrator must not allocate in its step loop (it refactors every few steps when the
//! step size moves). Speed is no reason either way: in the integrator on the static-valve
//! moves both took the same CPU time (0.22 s for 3 simulated s), and in isolation at
//! n = 22 one solve cost about as much as one right-hand side of the bench with either.
//! The substitutions are contiguous dot products with four running sums (perf showed a
//! single running sum latency-bound). The unit test checks it against nalgebra's LU.

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
}

impl DenseLu {
    pub fn new(n: usize) -> DenseLu {
        DenseLu {
            n,
            a: vec![0.0; n * n],
            inv_diag: vec![0.0; n],
            pivots: (0..n).collect(),
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
        true
    }

    /// Solve A x = b in place (b becomes x).
    pub fn solve(&self, b: &mut [f64]) {
        let n = self.n;
        for (k, &p) in self.pivots.iter().enumerate() {
            b.swap(k, p);
        }
        for i in 1..n {
            let s = dot(&self.a[i * n..i * n + i], &b[..i]);
            b[i] -= s;
        }
        for i in (0..n).rev() {
            let s = dot(&self.a[i * n + i + 1..(i + 1) * n], &b[i + 1..]);
            b[i] = (b[i] - s) * self.inv_diag[i];
        }
    }
}

/// Dot product with four independent sums: a single running sum is a chain of dependent
/// additions, whose latency bounds the substitutions at n = 22.
fn dot(a: &[f64], b: &[f64]) -> f64 {
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

    #[test]
    fn a_singular_matrix_is_refused() {
        let mut lu = DenseLu::new(2);
        lu.matrix_mut().copy_from_slice(&[1.0, 2.0, 2.0, 4.0]);
        assert!(!lu.factorise());
    }
}
