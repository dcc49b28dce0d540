//! A sustained oscillation in the record that the model does not have (issue 14 item 5,
//! localisation).
//!
//! With the manifold's oil mass 1.44 times the built-in one hidden on the slow moves
//! (Rust bench, form error, seed 1), the bench's load pressure oscillates at 212 Hz,
//! growing to 7.2 bar RMS in 0.50-0.75 s, while the known model stays quiet. Least squares
//! in time cannot follow a self-excited oscillation: its phase is set by what started it,
//! so a candidate that oscillates at the right frequency and size but another phase
//! leaves a residual larger than one that does not oscillate at all. Every candidate
//! then fails and the report said only "no candidate effect lowers the gap (25.55)",
//! with no word on why (measured, session 30). The localisation now says what the
//! residual is: in the window where the disagreement is largest, one sinusoid fitted to
//! the residual of the load pressure (of y when the record has no pressures), its
//! frequency, and how large it is in the measured and in the simulated signal.

use std::f64::consts::PI;
use std::ops::Range;

use rustfft::{num_complex::Complex, FftPlanner};
use serde::Serialize;

use super::data::Measured;
use super::drive::Traces;
use super::resonance::hann;

/// An oscillation the record carries and the model lacks, in one time window.
#[derive(Debug, Clone, Serialize)]
pub struct Oscillation {
    /// "P1 - P2" or "y".
    pub signal: String,
    pub start: f64,
    pub end: f64,
    pub frequency_hz: f64,
    /// RMS of the sinusoid at `frequency_hz` in the measured signal (SI).
    pub measured_rms: f64,
    /// The same in the simulated signal.
    pub simulated_rms: f64,
    /// Share of the window's residual variance (trend removed) that the sinusoid holds.
    pub share: f64,
}

/// Least share of the residual's variance one sinusoid must hold for the residual to be
/// called an oscillation: more than the rest together. Broadband misfit (a wrong damping
/// over a step's ringing, a lag) spreads over many frequencies and stays below it.
pub const MIN_SHARE: f64 = 0.5;
/// The measured sinusoid is at least this many times the simulated one: the model lacks
/// the oscillation, rather than having it at another size (a gain error, which the
/// frequency bands report).
const LACKED: f64 = 3.0;
/// The measured sinusoid's RMS is at least this many times the signal's noise. White
/// noise alone, detrended, gives its largest sinusoid over a 125-sample window an RMS of
/// 0.24 noise levels (median of 2000 draws; 0.42 at the 99.9th percentile, 0.47 at
/// most; numpy, session 30), so noise is never called an oscillation; 5 keeps the line
/// for oscillations that stand out of a trace by eye, where the residual's gap (in noise
/// levels) is large enough for the window to be the worst.
const ABOVE_NOISE: f64 = 5.0;
/// Least whole cycles in the window: slower content is the record's moves, not an
/// oscillation.
const MIN_CYCLES: f64 = 3.0;
/// Zero-padding factor of the periodogram: 16 places the peak of a pure sinusoid within
/// a 64th of the window's frequency resolution before it is refined.
const PADDING: usize = 16;

/// The oscillation in `window` of the record, if its residual is one: the load pressure
/// P1 - P2 when the record has P1 and P2, else y. `noise` is that signal's noise (SI).
pub fn find(m: &Measured, sim: &Traces, window: Range<usize>, noise: f64) -> Option<Oscillation> {
    let (signal, measured, simulated) = load_signal(m, sim, window.clone())?;
    let n = measured.len();
    let period = m.period();
    if n < 16 || period.is_nan() || period <= 0.0 {
        return None;
    }
    let residual: Vec<f64> = measured
        .iter()
        .zip(&simulated)
        .map(|(a, b)| a - b)
        .collect();
    let detrended = detrend(&residual);
    let variance = detrended.iter().map(|x| x * x).sum::<f64>() / n as f64;
    if variance.is_nan() || variance <= 0.0 {
        return None;
    }
    let f0 = peak_frequency(&detrended, period)?;
    let explained = sinusoid(&residual, period, f0).powi(2);
    let share = explained / variance;
    let measured_rms = sinusoid(&measured, period, f0);
    let simulated_rms = sinusoid(&simulated, period, f0);
    let lacked = measured_rms >= LACKED * simulated_rms;
    if share < MIN_SHARE || !lacked || measured_rms < ABOVE_NOISE * noise {
        return None;
    }
    Some(Oscillation {
        signal,
        start: m.time[window.start],
        end: m.time[window.end - 1],
        frequency_hz: f0,
        measured_rms,
        simulated_rms,
        share,
    })
}

/// The compared signal over `window`, measured and simulated.
fn load_signal(
    m: &Measured,
    sim: &Traces,
    window: Range<usize>,
) -> Option<(String, Vec<f64>, Vec<f64>)> {
    let load =
        |p1: &[f64], p2: &[f64]| -> Vec<f64> { window.clone().map(|k| p1[k] - p2[k]).collect() };
    match (m.get("P1"), m.get("P2"), sim.get("P1"), sim.get("P2")) {
        (Some(a1), Some(a2), Some(b1), Some(b2)) => {
            Some(("P1 - P2".into(), load(a1, a2), load(b1, b2)))
        }
        _ => {
            let (a, b) = (m.get("y")?, sim.get("y")?);
            Some(("y".into(), a[window.clone()].to_vec(), b[window].to_vec()))
        }
    }
}

/// `x` less its least-squares straight line.
fn detrend(x: &[f64]) -> Vec<f64> {
    let n = x.len() as f64;
    let mean_k = (n - 1.0) / 2.0;
    let mean_x = x.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (k, v) in x.iter().enumerate() {
        let dk = k as f64 - mean_k;
        sxy += dk * (v - mean_x);
        sxx += dk * dk;
    }
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    x.iter()
        .enumerate()
        .map(|(k, v)| v - mean_x - slope * (k as f64 - mean_k))
        .collect()
}

/// Frequency of the largest peak of `x`'s Hann-windowed, zero-padded periodogram above
/// MIN_CYCLES per window and below 0.45 of the sampling rate (the anti-alias edge),
/// refined by a parabola through the peak's log magnitudes.
fn peak_frequency(x: &[f64], period: f64) -> Option<f64> {
    let n = x.len();
    let nfft = n.next_power_of_two() * PADDING;
    let taper = hann(n);
    let mut buf: Vec<Complex<f64>> = (0..nfft)
        .map(|k| Complex::new(if k < n { x[k] * taper[k] } else { 0.0 }, 0.0))
        .collect();
    FftPlanner::new().plan_fft_forward(nfft).process(&mut buf);
    let df = 1.0 / (nfft as f64 * period);
    let lo = (MIN_CYCLES / (n as f64 * period) / df).ceil() as usize;
    let hi = ((0.45 / period) / df).floor() as usize;
    if lo + 1 >= hi {
        return None;
    }
    let k = (lo..=hi).max_by(|a, b| buf[*a].norm_sqr().total_cmp(&buf[*b].norm_sqr()))?;
    let ln = |j: usize| buf[j].norm_sqr().max(1e-300).ln();
    let offset = if k > lo && k < hi {
        let (a, b, c) = (ln(k - 1), ln(k), ln(k + 1));
        let d = a - 2.0 * b + c;
        if d < 0.0 {
            0.5 * (a - c) / d
        } else {
            0.0
        }
    } else {
        0.0
    };
    Some((k as f64 + offset) * df)
}

/// RMS of the sinusoid of frequency `f` in `x`, fitted by least squares beside a
/// constant and a straight line (the record's slow moves).
fn sinusoid(x: &[f64], period: f64, f: f64) -> f64 {
    let columns = |k: usize| {
        let t = k as f64 * period;
        let w = 2.0 * PI * f * t;
        [1.0, k as f64 / x.len() as f64, w.cos(), w.sin()]
    };
    let mut ata = nalgebra::Matrix4::<f64>::zeros();
    let mut atb = nalgebra::Vector4::<f64>::zeros();
    for (k, v) in x.iter().enumerate() {
        let a = nalgebra::Vector4::from(columns(k));
        ata += a * a.transpose();
        atb += a * *v;
    }
    let Some(c) = ata.try_inverse().map(|inv| inv * atb) else {
        return 0.0;
    };
    ((c[2] * c[2] + c[3] * c[3]) / 2.0).sqrt()
}

#[cfg(test)]
mod tests;
