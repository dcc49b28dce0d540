//! The Butcher tableau of Kennedy & Carpenter's ESDIRK3(2)4L[2]SA (NASA/TM-2016-219173,
//! section 5.2.1; the coefficients diffsol ships as `Tableau::esdirk34`), which
//! `solver::adaptive` integrates with, and the checks that the printed digits are the
//! method they claim to be: order conditions and L-stability.

/// Diagonal coefficient of ESDIRK3(2)4L[2]SA.
pub const GAMMA: f64 = 0.435_866_521_508_459;
/// Stage coefficients a_ij (row i, lower triangle, diagonal GAMMA), Kennedy & Carpenter.
pub const A: [[f64; 4]; 4] = [
    [0.0, 0.0, 0.0, 0.0],
    [GAMMA, GAMMA, 0.0, 0.0],
    [
        0.140_737_774_724_706_2,
        -0.108_365_551_381_320_8,
        GAMMA,
        0.0,
    ],
    [
        0.102_399_400_619_911,
        -0.376_878_452_255_556_1,
        0.838_612_530_127_186_1,
        GAMMA,
    ],
];
/// Stage times c_i (row sums of A).
pub const C: [f64; 4] = [0.0, 0.871_733_043_016_918, 0.468_238_744_851_844_4, 1.0];
/// b - b_hat: weights of the embedded error estimate (b is A's last row).
pub const D: [f64; 4] = [
    -0.054_625_497_240_413_94,
    -0.494_208_893_625_994_96,
    0.221_934_499_735_064_66,
    0.326_899_891_131_344_27,
];

#[cfg(test)]
mod tests {
    use super::*;

    /// The printed coefficients satisfy the order conditions: order 3 for b (A's last
    /// row), order 2 for the embedded b_hat = b - D, row sums c, stiffly accurate.
    #[test]
    fn tableau_has_the_orders_it_claims() {
        let b = A[3];
        let bh: Vec<f64> = (0..4).map(|i| b[i] - D[i]).collect();
        let close = |x: f64, y: f64| (x - y).abs() < 1e-14;
        for i in 0..4 {
            assert!(close(A[i].iter().sum::<f64>(), C[i]), "row {i}");
        }
        let sum = |w: &[f64], g: &dyn Fn(usize) -> f64| (0..4).map(|i| w[i] * g(i)).sum::<f64>();
        assert!(close(sum(&b, &|_| 1.0), 1.0));
        assert!(close(sum(&b, &|i| C[i]), 0.5));
        assert!(close(sum(&b, &|i| C[i] * C[i]), 1.0 / 3.0));
        let ac = |i: usize| (0..4).map(|j| A[i][j] * C[j]).sum::<f64>();
        assert!(close(sum(&b, &ac), 1.0 / 6.0));
        assert!(close(sum(&bh, &|_| 1.0), 1.0));
        assert!(close(sum(&bh, &|i| C[i]), 0.5));
        assert_eq!(C[3], 1.0);
    }

    /// L-stability: R(z) = 1 + z b^T (I - z A)^-1 1 tends to 0 as z -> -inf, and |R| <= 1
    /// on the imaginary axis (A-stability's boundary), evaluated numerically.
    #[test]
    fn stability_function_is_l_stable() {
        let r = |z: f64, w: f64| {
            // solve (I - z A) K = 1 for complex z = (z, w) by forward substitution
            let mut k = [(0.0, 0.0); 4];
            for i in 0..4 {
                let (mut re, mut im) = (1.0, 0.0);
                for j in 0..i {
                    // + z a_ij k_j
                    re += A[i][j] * (z * k[j].0 - w * k[j].1);
                    im += A[i][j] * (z * k[j].1 + w * k[j].0);
                }
                // divide by 1 - z a_ii
                let (dr, di) = (1.0 - z * A[i][i], -w * A[i][i]);
                let d2 = dr * dr + di * di;
                k[i] = ((re * dr + im * di) / d2, (im * dr - re * di) / d2);
            }
            let (mut re, mut im) = (1.0, 0.0);
            for j in 0..4 {
                re += A[3][j] * (z * k[j].0 - w * k[j].1);
                im += A[3][j] * (z * k[j].1 + w * k[j].0);
            }
            (re * re + im * im).sqrt()
        };
        assert!(r(-1e8, 0.0) < 1e-6, "{}", r(-1e8, 0.0));
        for w in [0.1, 1.0, 10.0, 100.0, 1e4] {
            assert!(r(0.0, w) <= 1.0 + 1e-12, "|R({w} i)| = {}", r(0.0, w));
        }
    }
}
