//! The resonance of a response, from a record: natural frequency and damping ratio of the
//! lightly damped pole pair that shapes it.
//!
//! Method. The record's DFTs X and Y (whole record, unwindowed) give the response
//! averaged over neighbouring bins, H = sum(X* Y) / sum(|X|^2), unbiased when only the
//! output carries noise (the input is the recorded reference or command), and its
//! coherence. The most prominent bump of the smoothed |H| gives the band. In that band a
//! local model
//!
//!   Y = exp(-s tau) ((b0 + b1 s + b2 s^2) X + I(s)) / (s^2 + a1 s + a0)
//!
//! is fitted by least squares to X and Y bin by bin, and the pole pair gives
//! wn = sqrt(a0) and zeta = a1 / (2 wn). I(s) takes the transient: the states at the
//! record's ends leak into every bin through the same poles.
//!
//! Why not the highest bin and the half-power width, as before:
//! - the magnitude of a second-order response peaks at wn sqrt(1 - 2 zeta^2), 9 % below wn
//!   at zeta = 0.3, and the -3 dB width only gives 2 zeta wn for light damping;
//! - the peak of |H| moves with what surrounds the pole pair: a closed loop's response to
//!   its reference falls towards the peak, the load pressure's rises as s^2, the open
//!   loop's position carries an integrator. The pole pair is the same in all of them;
//!   a free quadratic numerator absorbs these backgrounds, the peak bin does not;
//! - a single bin is noisy (a sweep spends little time at high frequencies), and the
//!   width around it is that of the noise: on the thesis bench's sweep (tests) the former
//!   pick read the measured resonance as 235 Hz with damping 0.006 and the simulated as
//!   274 Hz with 0.004; this fit reads 232 Hz with 0.054 and 292 Hz with 0.046, the
//!   measured y and P1 - P2 giving the same pole pair. The fit uses every bin of the
//!   band: the output error it minimises carries the output's white noise, equal in
//!   every bin;
//! - a delay (sensor, converter, the zero-order hold of the loop) turns the phase without
//!   changing the poles; the quadratic numerator cannot absorb a phase ramp over the band,
//!   so the delay is scanned and the fit with the smallest output error is kept.
//!
//! The linear fit is Levy's (multiply through by the denominator), refined by
//! Sanathanan-Koerner iterations (divide by the previous denominator), whose fixed point
//! minimises the output error |Y - model|. The band is sized from the damping found:
//! 2.5 zeta on each side of wn holds the half-power band and the flanks that fix zeta.

use std::f64::consts::PI;

use nalgebra::{SMatrix, SVector};
use rustfft::{num_complex::Complex, FftPlanner};
use serde::Serialize;

use super::data::Measured;
use super::drive::Traces;

/// Bins averaged on each side for the smoothed response and its coherence: 17 bins span
/// 6.8 Hz on a 2.5 s record, over which a bump of damping 0.05 at 200 Hz turns its phase
/// by about 40 deg, which lowers the coherence by about 4 % (computed, not measured).
const NEIGHBOURS: usize = 8;
/// Welch segments (the report's response): 1024 samples, about 1 Hz resolution at 1 kHz.
pub const SEGMENT: usize = 1024;
/// Bins whose measured coherence is below this are not used.
pub const COHERENCE: f64 = 0.8;
/// Bins whose input power is below this fraction of the strongest are not used: 60 dB
/// down (a log sweep's power falls as 1/f, 25 dB from 1 to 300 Hz), nothing drives the
/// bench there but the window's leakage.
pub const INPUT_POWER: f64 = 1e-6;
/// The same for the unwindowed DFT: 40 dB down. A sweep's power per bin spans 25 dB over
/// its band; beyond its last frequency the rectangular window's leakage, which carries no
/// response of the bench, falls below -40 dB within 10 Hz.
const DFT_INPUT_POWER: f64 = 1e-4;
/// Resonances are sought above 20 Hz (rad/s): the bench's hydraulic modes lie above
/// 100 Hz, and the position loop's own corner below is not a resonance.
const MIN_OMEGA: f64 = 2.0 * PI * 20.0;
/// Relative half-width of the smoothing of |H| (dB) before the bump is sought: 3 % spans
/// +-6 Hz at 200 Hz (30 bins of a 2.5 s record), enough to average a noisy bin away, and
/// lies within the half-power band (+-zeta) of any damping above 0.03.
const SMOOTH: f64 = 0.03;
/// A bump must stand this much (dB) above the lowest level within an octave on each side.
const PROMINENCE: f64 = 1.0;
/// First band: +-40 % around the bump; then 2.5 zeta around wn, within 15-60 %.
const FIRST_HALF_WIDTH: f64 = 0.4;
const BAND_DAMPINGS: f64 = 2.5;
const HALF_WIDTH: [f64; 2] = [0.15, 0.6];
/// At least this many bins in the band: twice the eight real parameters (each bin gives
/// two equations).
const MIN_BINS: usize = 16;
/// Delays scanned: up to half a period of the bump (pi of phase at wn), on a grid then by
/// golden section around the best node.
const DELAY_NODES: usize = 40;
const GOLDEN_STEPS: usize = 30;
const SK_ITERATIONS: usize = 30;

type Vector8<T> = SVector<T, 8>;
type Matrix8<T> = SMatrix<T, 8, 8>;

/// The periodic Hann window of `n` samples, as the spectra of the gap workflow taper
/// their segments (Welch's spectra here, the noise estimate, the oscillation's
/// periodogram).
pub fn hann(n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| 0.5 - 0.5 * (2.0 * PI * k as f64 / n as f64).cos())
        .collect()
}

/// Cross and auto spectra of x -> y by Welch's method (Hann, 50 % overlap): frequencies
/// (Hz), Sxy, Sxx, Syy.
pub fn spectra(
    x: &[f64],
    y: &[f64],
    period: f64,
) -> (Vec<f64>, Vec<Complex<f64>>, Vec<f64>, Vec<f64>) {
    let n = SEGMENT.min(x.len().next_power_of_two() / 2).max(16);
    let fft = FftPlanner::new().plan_fft_forward(n);
    let hann = hann(n);
    let mut sxy = vec![Complex::new(0.0, 0.0); n / 2];
    let (mut sxx, mut syy) = (vec![0.0; n / 2], vec![0.0; n / 2]);
    // half-overlapping segments, the last one flush with the end so the record's tail
    // (a sweep's highest frequencies) is analysed too
    let mut starts: Vec<usize> = (0..)
        .map(|k| k * n / 2)
        .take_while(|s| s + n <= x.len())
        .collect();
    if starts.last().is_some_and(|&s| s + n < x.len()) {
        starts.push(x.len() - n);
    }
    for start in starts {
        let seg = |s: &[f64]| -> Vec<Complex<f64>> {
            let mean = s[start..start + n].iter().sum::<f64>() / n as f64;
            let mut b: Vec<Complex<f64>> = (0..n)
                .map(|k| Complex::new((s[start + k] - mean) * hann[k], 0.0))
                .collect();
            fft.process(&mut b);
            b
        };
        let (fx, fy) = (seg(x), seg(y));
        for k in 0..n / 2 {
            sxy[k] += fx[k].conj() * fy[k];
            sxx[k] += fx[k].norm_sqr();
            syy[k] += fy[k].norm_sqr();
        }
    }
    let freq = (0..n / 2).map(|k| k as f64 / (n as f64 * period)).collect();
    (freq, sxy, sxx, syy)
}

/// A frequency response estimated from a record, on the bins of the whole record's DFT.
pub struct Frf {
    /// Angular frequency of each bin (rad/s).
    pub omega: Vec<f64>,
    /// The record's DFTs.
    pub x: Vec<Complex<f64>>,
    pub y: Vec<Complex<f64>>,
    /// H1 estimate averaged over NEIGHBOURS bins on each side (Daniell).
    pub h: Vec<Complex<f64>>,
    /// Bins the fit may use: driven by the input and, for a measured response, coherent
    /// (over the same neighbours).
    pub usable: Vec<bool>,
}

/// The response x -> y of a record; `noisy`: y is measured, and only its coherent bins
/// are usable.
///
/// The whole record, unwindowed, and averaged over neighbouring bins rather than over
/// Welch's segments: a sweep reaches its top frequencies in the record's last tenth,
/// where the last Hann segment tapers them away (on the thesis bench's sweep, Welch's
/// bins lost their coherence above 230 Hz, hiding the right flank of a 225 Hz bump), and
/// the fit's transient term takes what the unwindowed edges leak. A Hann window would also
/// weigh the input and the ringing output that lags it unequally where the sweep crosses
/// the resonance near a segment's edge: fitting Welch's H1 read damping 0.1 as 0.108 on a
/// 2.5 s sweep (measured).
pub fn frf(x: &[f64], y: &[f64], period: f64, noisy: bool) -> Frf {
    let n = x.len().min(y.len());
    let fft = FftPlanner::new().plan_fft_forward(n);
    let dft = |v: &[f64]| {
        let mean = v[..n].iter().sum::<f64>() / n as f64;
        let mut b: Vec<Complex<f64>> = v[..n].iter().map(|a| Complex::new(a - mean, 0.0)).collect();
        fft.process(&mut b);
        b.truncate(n / 2);
        b
    };
    let (dx, dy) = (dft(x), dft(y));
    let bins = n / 2;
    let (mut sxy, mut sxx, mut syy) = (
        vec![Complex::new(0.0, 0.0); bins],
        vec![0.0; bins],
        vec![0.0; bins],
    );
    for k in 1..bins {
        for j in k.saturating_sub(NEIGHBOURS).max(1)..(k + NEIGHBOURS + 1).min(bins) {
            sxy[k] += dx[j].conj() * dy[j];
            sxx[k] += dx[j].norm_sqr();
            syy[k] += dy[j].norm_sqr();
        }
    }
    let peak = sxx.iter().copied().fold(0.0, f64::max);
    let usable = (0..bins)
        .map(|k| {
            let driven = k > 0 && sxx[k] > DFT_INPUT_POWER * peak;
            let coherent = sxy[k].norm_sqr() / (sxx[k] * syy[k]).max(1e-300) > COHERENCE;
            driven && (coherent || !noisy)
        })
        .collect();
    Frf {
        omega: (0..bins)
            .map(|k| 2.0 * PI * k as f64 / (n as f64 * period))
            .collect(),
        h: sxy
            .iter()
            .zip(&sxx)
            .map(|(s, x)| s / x.max(1e-300))
            .collect(),
        x: dx,
        y: dy,
        usable,
    }
}

/// The first difference of `y` over `period` (a velocity from a position) and the input
/// samples it pairs with: an open loop's position integrates the valve's flow, so its bump
/// only stands out on the velocity, and its wander over the record would leak through
/// the record's edges into every bin of the DFT. The difference is jw in discrete time
/// (times a half-sample delay and a sinc, which the fit's delay and numerator absorb).
pub fn difference<'a>(x: &'a [f64], y: &[f64], period: f64) -> (&'a [f64], Vec<f64>) {
    let v = y.windows(2).map(|w| (w[1] - w[0]) / period).collect();
    (&x[1.min(x.len())..], v)
}

/// A resonant pole pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mode {
    /// Undamped natural frequency (rad/s).
    pub natural_frequency: f64,
    pub damping: f64,
    /// The pure delay fitted with it (s).
    pub delay: f64,
}

/// The resonance of a response: its most prominent bump, fitted by a pole pair.
pub fn mode(f: &Frf) -> Option<Mode> {
    let center = bump(f)?;
    let mut m = fit_band(f, center, FIRST_HALF_WIDTH)?;
    // the band follows the fit: twice is enough for the band to settle (measured on the
    // tests' records, a third pass changes wn by less than 0.1 %)
    for _ in 0..2 {
        let half = (BAND_DAMPINGS * m.damping).clamp(HALF_WIDTH[0], HALF_WIDTH[1]);
        m = fit_band(f, m.natural_frequency, half)?;
    }
    Some(m)
}

/// Angular frequency of the most prominent bump of the smoothed |H|: the one standing
/// highest over the lowest level within an octave below and above it (a closed-loop
/// response falls towards its resonance, a pressure response rises, so a bump is not the
/// maximum), if it stands PROMINENCE or more.
fn bump(f: &Frf) -> Option<f64> {
    let idx: Vec<usize> = (0..f.omega.len())
        .filter(|&k| f.usable[k] && f.omega[k] >= MIN_OMEGA)
        .collect();
    let db: Vec<f64> = idx
        .iter()
        .map(|&k| 20.0 * f.h[k].norm().max(1e-300).log10())
        .collect();
    let w: Vec<f64> = idx.iter().map(|&k| f.omega[k]).collect();
    let smooth: Vec<f64> = (0..idx.len())
        .map(|i| {
            let near: Vec<f64> = (0..idx.len())
                .filter(|&j| (w[j] / w[i] - 1.0).abs() <= SMOOTH)
                .map(|j| db[j])
                .collect();
            near.iter().sum::<f64>() / near.len() as f64
        })
        .collect();
    let lowest = |i: usize, lo: f64, hi: f64| {
        (0..idx.len())
            .filter(|&j| w[j] >= lo * w[i] && w[j] <= hi * w[i])
            .map(|j| smooth[j])
            .fold(f64::INFINITY, f64::min)
    };
    let prominence = |i: usize| smooth[i] - lowest(i, 0.5, 1.0).max(lowest(i, 1.0, 2.0));
    let best = (0..idx.len()).max_by(|a, b| prominence(*a).total_cmp(&prominence(*b)))?;
    (prominence(best) >= PROMINENCE).then_some(w[best])
}

/// The pole pair fitted to the DFT bins within `half` (relative) of `center`, with the
/// delay that leaves the smallest output error.
fn fit_band(f: &Frf, center: f64, half: f64) -> Option<Mode> {
    let bins: Vec<usize> = (0..f.omega.len())
        .filter(|&k| f.usable[k] && (f.omega[k] / center - 1.0).abs() <= half)
        .collect();
    if bins.len() < MIN_BINS {
        return None;
    }
    let error = |tau: f64| sk_fit(f, &bins, center, tau).map_or(f64::INFINITY, |r| r.0);
    let max_delay = PI / center;
    let step = max_delay / (DELAY_NODES - 1) as f64;
    let errors: Vec<f64> = (0..DELAY_NODES).map(|i| error(i as f64 * step)).collect();
    let best = (0..DELAY_NODES).min_by(|a, b| errors[*a].total_cmp(&errors[*b]))?;
    // golden section in the two intervals around the best node
    let (mut a, mut b) = (
        best.saturating_sub(1) as f64 * step,
        (best + 1).min(DELAY_NODES - 1) as f64 * step,
    );
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut ec, mut ed) = (error(c), error(d));
    for _ in 0..GOLDEN_STEPS {
        if ec < ed {
            (b, d, ed) = (d, c, ec);
            c = b - g * (b - a);
            ec = error(c);
        } else {
            (a, c, ec) = (c, d, ed);
            d = a + g * (b - a);
            ed = error(d);
        }
    }
    let tau = 0.5 * (a + b);
    let (_, a0, a1) = sk_fit(f, &bins, center, tau)?;
    // a complex pair: a0 > 0 and 0 < zeta < 1
    if a0 <= 0.0 || a1 <= 0.0 || a1 * a1 >= 4.0 * a0 {
        return None;
    }
    Some(Mode {
        natural_frequency: center * a0.sqrt(),
        damping: a1 / (2.0 * a0.sqrt()),
        delay: tau,
    })
}

/// Sanathanan-Koerner fit of D(s) Y = exp(-s tau) (N(s) X + I(s)) on the DFT `bins`, s
/// normalised by `center`: the output error and the denominator's a0, a1. I(s), a real
/// quadratic like N, is the transient term: the states at the record's start and end
/// leak into every bin through the same poles (Pintelon and Schoukens' frequency-domain
/// identification), so the record need not start or end at rest. X and Y are scaled to
/// unit RMS over the band, which keeps the normal equations balanced.
fn sk_fit(f: &Frf, bins: &[usize], center: f64, tau: f64) -> Option<(f64, f64, f64)> {
    let rms = |v: &[Complex<f64>]| {
        (bins.iter().map(|&k| v[k].norm_sqr()).sum::<f64>() / bins.len() as f64)
            .sqrt()
            .max(1e-300)
    };
    let (sx, sy) = (rms(&f.x), rms(&f.y));
    let s: Vec<Complex<f64>> = bins
        .iter()
        .map(|&k| Complex::new(0.0, f.omega[k] / center))
        .collect();
    let x: Vec<Complex<f64>> = bins.iter().map(|&k| f.x[k] / sx).collect();
    // the output with the delay taken out
    let y: Vec<Complex<f64>> = bins
        .iter()
        .map(|&k| f.y[k] / sy * Complex::from_polar(1.0, f.omega[k] * tau))
        .collect();
    let quadratic =
        |p: &Vector8<f64>, o: usize, s: Complex<f64>| p[o] + p[o + 1] * s + p[o + 2] * s * s;
    let denominator = |p: &Vector8<f64>, s: Complex<f64>| s * s + p[4] * s + p[3];
    let mut p: Option<Vector8<f64>> = None;
    for _ in 0..SK_ITERATIONS {
        let (mut ata, mut atb) = (Matrix8::<f64>::zeros(), Vector8::<f64>::zeros());
        for i in 0..bins.len() {
            // N X + I - Y (a0 + a1 s) = Y s^2, divided by the previous |D|
            let scale = 1.0 / p.as_ref().map_or(1.0, |p| denominator(p, s[i]).norm());
            let (si, xi, yi) = (s[i], x[i], y[i]);
            let row = [
                xi,
                xi * si,
                xi * si * si,
                -yi,
                -yi * si,
                1.0.into(),
                si,
                si * si,
            ]
            .map(|c: Complex<f64>| c * scale);
            let rhs = yi * si * si * scale;
            for part in [|c: Complex<f64>| c.re, |c: Complex<f64>| c.im] {
                let r = Vector8::from_fn(|j, _| part(row[j]));
                ata += r * r.transpose();
                atb += r * part(rhs);
            }
        }
        let next = ata.lu().solve(&atb)?;
        let settled = p.is_some_and(|q| {
            (next[3] - q[3]).abs() + (next[4] - q[4]).abs() < 1e-12 * (1.0 + next[3].abs())
        });
        p = Some(next);
        if settled {
            break;
        }
    }
    let p = p?;
    let error = (0..bins.len())
        .map(|i| {
            let model =
                (quadratic(&p, 0, s[i]) * x[i] + quadratic(&p, 5, s[i])) / denominator(&p, s[i]);
            (y[i] - model).norm_sqr()
        })
        .sum::<f64>();
    error.is_finite().then_some((error, p[3], p[4]))
}

/// The resonance of one response of the bench, in the measured and the simulated record.
#[derive(Debug, Clone, Serialize)]
pub struct Resonance {
    /// Which response: input -> output, as the record names them.
    pub response: String,
    /// Undamped natural frequency of the fitted pole pair (Hz).
    pub measured_hz: f64,
    pub simulated_hz: f64,
    /// Damping ratio of the pole pair.
    pub measured_damping: f64,
    pub simulated_damping: f64,
}

/// The resonances of the responses of y and of P1 - P2 to the record's input
/// (`input_name`: the reference in closed loop, the command u1 in open loop), measured and
/// simulated; None where either record shows no resonance.
pub fn resonances(
    m: &Measured,
    sim: &Traces,
    input_name: &str,
    open_loop: bool,
) -> (Option<Resonance>, Option<Resonance>) {
    let Some(x) = m.get(input_name).filter(|x| x.len() >= 256) else {
        return (None, None);
    };
    let period = m.period();
    let load = |p1: Option<&[f64]>, p2: Option<&[f64]>| -> Option<Vec<f64>> {
        Some(p1?.iter().zip(p2?).map(|(a, b)| a - b).collect())
    };
    let pair = |response: String, measured: Option<&[f64]>, simulated: Option<&[f64]>, s: bool| {
        let estimate = |y: &[f64], noisy: bool| {
            if s {
                let (x, v) = difference(x, y, period);
                mode(&frf(x, &v, period, noisy))
            } else {
                mode(&frf(x, y, period, noisy))
            }
        };
        let (a, b) = (estimate(measured?, true)?, estimate(simulated?, false)?);
        let hz = |m: &Mode| m.natural_frequency / (2.0 * PI);
        Some(Resonance {
            response,
            measured_hz: hz(&a),
            simulated_hz: hz(&b),
            measured_damping: a.damping,
            simulated_damping: b.damping,
        })
    };
    let position = pair(
        if open_loop {
            format!("{input_name} -> dy/dt")
        } else {
            format!("{input_name} -> y")
        },
        m.get("y"),
        sim.get("y"),
        open_loop,
    );
    let (pm, ps) = (
        load(m.get("P1"), m.get("P2")),
        load(sim.get("P1"), sim.get("P2")),
    );
    let pressure = pair(
        format!("{input_name} -> P1-P2"),
        pm.as_deref(),
        ps.as_deref(),
        false,
    );
    (position, pressure)
}

#[cfg(test)]
mod tests;
