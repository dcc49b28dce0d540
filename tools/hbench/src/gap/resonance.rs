//! The resonance of a frequency-response estimate: natural frequency and damping ratio of
//! its dominant lightly damped pole pair.
//!
//! A closed-loop response falls with frequency, so its resonance is a bump on a slope, not
//! the maximum, and the half-power width of that bump says little about the damping. The
//! bump is located by its prominence, then a second-order rational model
//! (b0 + b1 s + b2 s^2) / (a0 + a1 s + s^2) is fitted to the complex response on the bins
//! around it by Sanathanan-Koerner iterations (Levy's linearisation, reweighted by the
//! previous denominator); the numerator takes up the slope. The pole pair gives
//! wn = sqrt(a0) and zeta = a1 / (2 sqrt(a0)).

use nalgebra::{DMatrix, DVector};
use rustfft::num_complex::Complex;

/// Lowest frequency at which a resonance is sought (Hz): below it lie the closed loop's
/// bandwidth and the slow drifts, not the oil columns.
const LOWEST: f64 = 50.0;
/// A bump that stands less than this over the lowest point between half its frequency
/// and itself (dB) is no resonance.
const PROMINENCE_DB: f64 = 2.0;
/// The fit uses the bins within this factor of the bump's frequency: wide enough to hold
/// the half-power points of a damping ratio up to 0.3, narrow enough to leave out the next
/// dynamics (the valve's bandwidth, the sampling's Nyquist frequency).
const WINDOW: f64 = 1.5;
/// Sanathanan-Koerner iterations (converged to 1e-6 in 3-4 on the tests' records).
const ITERATIONS: usize = 8;

/// The bin above LOWEST whose level stands highest over the lowest point between half its
/// frequency and itself.
fn bump(freq: &[f64], db: &[f64], ok: &[bool]) -> Option<usize> {
    let idx: Vec<usize> = (0..freq.len())
        .filter(|&k| ok[k] && freq[k] >= LOWEST)
        .collect();
    let prominence = |k: usize| {
        let valley = idx
            .iter()
            .filter(|&&j| freq[j] >= 0.5 * freq[k] && j <= k)
            .map(|&j| db[j])
            .fold(f64::INFINITY, f64::min);
        db[k] - valley
    };
    let &k = idx
        .iter()
        .max_by(|a, b| prominence(**a).total_cmp(&prominence(**b)))?;
    (prominence(k) >= PROMINENCE_DB).then_some(k)
}

/// Natural frequency (Hz) and damping ratio of the response's resonance, if it has one.
pub fn resonance(freq: &[f64], h: &[Complex<f64>], ok: &[bool]) -> Option<(f64, f64)> {
    let db: Vec<f64> = h
        .iter()
        .map(|h| 20.0 * h.norm().max(1e-300).log10())
        .collect();
    let k = bump(freq, &db, ok)?;
    let f0 = freq[k];
    let bins: Vec<usize> = (0..freq.len())
        .filter(|&j| ok[j] && freq[j] >= f0 / WINDOW && freq[j] <= f0 * WINDOW)
        .collect();
    if bins.len() < 8 {
        return None;
    }
    // s in units of the bump's angular frequency: a well-conditioned system
    let s: Vec<Complex<f64>> = bins
        .iter()
        .map(|&j| Complex::new(0.0, freq[j] / f0))
        .collect();
    let hb: Vec<Complex<f64>> = bins.iter().map(|&j| h[j]).collect();
    // unknowns a0, a1, b0, b1, b2; rows: real and imaginary parts of
    // H (a0 + a1 s) - (b0 + b1 s + b2 s^2) = -H s^2, each divided by |D_previous(s)|
    let (mut a0, mut a1) = (1.0, 0.2);
    for _ in 0..ITERATIONS {
        let mut m = DMatrix::zeros(2 * bins.len(), 5);
        let mut rhs = DVector::zeros(2 * bins.len());
        for (i, (s, h)) in s.iter().zip(&hb).enumerate() {
            let w = 1.0 / (a0 + a1 * s + s * s).norm().max(1e-9);
            let cols = [*h, h * s, -Complex::new(1.0, 0.0), -s, -s * s];
            let r = -h * s * s;
            for (c, v) in cols.iter().enumerate() {
                m[(2 * i, c)] = v.re * w;
                m[(2 * i + 1, c)] = v.im * w;
            }
            rhs[2 * i] = r.re * w;
            rhs[2 * i + 1] = r.im * w;
        }
        let x = m.svd(true, true).solve(&rhs, 1e-12).ok()?;
        (a0, a1) = (x[0], x[1]);
        if !(a0 > 0.0 && a1.is_finite()) {
            return None;
        }
    }
    let wn = a0.sqrt();
    let zeta = a1 / (2.0 * wn);
    (zeta > 0.0 && zeta < 1.0).then_some((wn * f0, zeta))
}

/// Phase in degrees without its 360-degree jumps: each step between neighbouring values
/// taken as the shortest turn.
pub fn unwrap_deg(deg: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(deg.len());
    let mut offset = 0.0_f64;
    for (k, d) in deg.iter().enumerate() {
        if k > 0 {
            let step: f64 = d + offset - out[k - 1];
            offset -= 360.0 * (step / 360.0).round();
        }
        out.push(d + offset);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use std::f64::consts::PI;

    /// A closed loop of known resonance sampled at 1 kHz: a first-order lag of 30 Hz
    /// bandwidth times a pole pair (fn, zeta), driven by the sweep experiment's 1-300 Hz
    /// log sweep over 2.5 s, integrated by RK4 with 20 substeps per sample, noise added.
    fn record(fn_hz: f64, zeta: f64) -> (Vec<f64>, Vec<f64>) {
        let (dt, n, sub) = (1e-3, 2500, 20);
        let wn = 2.0 * PI * fn_hz;
        let wc = 2.0 * PI * 30.0;
        let rate = (300f64).ln() / 2.5;
        let x: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 * dt;
                (2.0 * PI * ((rate * t).exp() - 1.0) / rate).sin()
            })
            .collect();
        // states: lag output q, pole pair position p and rate v
        let f = |s: [f64; 3], u: f64| {
            [
                wc * (u - s[0]),
                s[2],
                wn * wn * (s[0] - s[1]) - 2.0 * zeta * wn * s[2],
            ]
        };
        let mut s = [0.0; 3];
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let noise = Normal::new(0.0, 1e-3).unwrap();
        let mut y = Vec::with_capacity(n);
        for &u in &x {
            y.push(s[1] + noise.sample(&mut rng));
            let h = dt / sub as f64;
            for _ in 0..sub {
                let add = |a: [f64; 3], b: [f64; 3], c: f64| {
                    [a[0] + c * b[0], a[1] + c * b[1], a[2] + c * b[2]]
                };
                let k1 = f(s, u);
                let k2 = f(add(s, k1, h / 2.0), u);
                let k3 = f(add(s, k2, h / 2.0), u);
                let k4 = f(add(s, k3, h), u);
                for i in 0..3 {
                    s[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
                }
            }
        }
        (x, y)
    }

    #[test]
    fn known_resonances_are_found_within_5_percent() {
        for (fn_hz, zeta) in [(200.0, 0.1), (150.0, 0.2), (120.0, 0.05)] {
            let (x, y) = record(fn_hz, zeta);
            let (freq, sxy, sxx, syy) = super::super::analysis::spectra(&x, &y, 1e-3);
            let h: Vec<Complex<f64>> = sxy.iter().zip(&sxx).map(|(s, x)| s / x).collect();
            let ok: Vec<bool> = (0..freq.len())
                .map(|k| {
                    freq[k] > 1.0 && freq[k] < 300.0 && sxy[k].norm_sqr() / (sxx[k] * syy[k]) > 0.8
                })
                .collect();
            let (f, z) = resonance(&freq, &h, &ok).expect("a resonance");
            assert!((f / fn_hz - 1.0).abs() < 0.05, "{f} Hz for {fn_hz}");
            assert!((z / zeta - 1.0).abs() < 0.05, "zeta {z} for {zeta}");
        }
    }

    #[test]
    fn phase_unwraps_through_the_jumps() {
        let true_deg: Vec<f64> = (0..100).map(|k| -7.3 * k as f64).collect();
        let wrapped: Vec<f64> = true_deg
            .iter()
            .map(|d| (d + 180.0f64).rem_euclid(360.0) - 180.0)
            .collect();
        let u = unwrap_deg(&wrapped);
        for (a, b) in u.iter().zip(&true_deg) {
            assert!((a - b).abs() < 1e-9, "{a} {b}");
        }
    }
}
