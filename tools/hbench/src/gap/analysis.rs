//! Where simulation and measurement disagree: per signal, per time window and per
//! frequency band (frequency-response estimates of the measured and the simulated bench
//! from the same input); the noise floor the gaps are counted in is `noise`'s.

use std::f64::consts::PI;
use std::ops::Range;

use rustfft::num_complex::Complex;
use serde::Serialize;

use super::data::{Drive, Experiment, Measured};
use super::drive::Traces;
pub use super::oscillation::Oscillation;
pub use super::resonance::Resonance;
use super::resonance::{resonances, spectra, COHERENCE, INPUT_POWER};

/// What the acquisition can read of each compared signal (SI): a simulated value beyond
/// it is compared as the saturated converter would record it (the pressure sensors read
/// up to 206 bar, below the 210 bar supply the chambers reach at full command).
pub fn sensor_range(signal: &str) -> [f64; 2] {
    let sp = hbmodel::sensors::SensorParams::default();
    let range = if signal == "y" {
        sp.position_range
    } else {
        sp.pressure_range
    };
    [range[0], range[1] - quantum(signal)]
}

/// The 16-bit quantum of each compared signal (m, Pa): LVDT 0.3 m, pressure 206 bar.
pub fn quantum(signal: &str) -> f64 {
    match signal {
        "y" => 0.3 / 65536.0,
        _ => 206e5 / 65536.0,
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct SignalGap {
    pub signal: String,
    /// RMS of measured - simulated (SI).
    pub rms: f64,
    pub noise: f64,
    /// Mean of measured - simulated (SI): a static offset.
    pub offset: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct WindowGap {
    pub start: f64,
    pub end: f64,
    /// RMS of the normalised residuals of all compared signals in the window.
    pub gap: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct BandGap {
    pub low_hz: f64,
    pub high_hz: f64,
    /// 20 log10 |H_measured / H_simulated| over the band's coherent bins (dB).
    pub gain_db: f64,
    /// arg(H_measured / H_simulated) (deg, negative: the bench lags the model).
    pub phase_deg: f64,
    pub bins: usize,
}

/// Frequency response of y to the experiment's input (reference or command).
#[derive(Debug, Clone, Serialize)]
pub struct Response {
    pub freq: Vec<f64>,
    pub measured_db: Vec<f64>,
    pub simulated_db: Vec<f64>,
    pub measured_deg: Vec<f64>,
    pub simulated_deg: Vec<f64>,
    pub coherent: Vec<bool>,
    /// Bins the input drives (the simulated response is noiseless: no coherence needed).
    pub driven: Vec<bool>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Localisation {
    pub signals: Vec<SignalGap>,
    pub windows: Vec<WindowGap>,
    pub bands: Vec<BandGap>,
    /// Resonance of y's response to the input (of its velocity's in open loop).
    pub resonance: Option<Resonance>,
    /// Resonance of the load pressure P1 - P2's response to the input.
    pub pressure_resonance: Option<Resonance>,
    /// Delay that best explains the phase difference over the coherent bins (s).
    pub equivalent_delay: Option<f64>,
    /// The oscillation the record carries and the model lacks in the window of largest
    /// disagreement, if the residual there is one (`oscillation`).
    pub oscillation: Option<Oscillation>,
    #[serde(skip)]
    pub response: Option<Response>,
}

const WINDOWS: usize = 8;
const BANDS: [[f64; 2]; 5] = [
    [1.0, 3.0],
    [3.0, 10.0],
    [10.0, 30.0],
    [30.0, 100.0],
    [100.0, 300.0],
];
fn response(m: &Measured, sim: &Traces, input: &[f64]) -> Response {
    let period = m.period();
    let (freq, sxy_m, sxx, syy_m) = spectra(input, m.get("y").unwrap_or(&[]), period);
    let (_, sxy_s, _, _) = spectra(input, sim.get("y").unwrap_or(&[]), period);
    let db = |h: Complex<f64>| 20.0 * h.norm().max(1e-30).log10();
    let deg = |h: Complex<f64>| h.arg().to_degrees();
    let hm: Vec<_> = sxy_m
        .iter()
        .zip(&sxx)
        .map(|(s, x)| s / x.max(1e-300))
        .collect();
    let hs: Vec<_> = sxy_s
        .iter()
        .zip(&sxx)
        .map(|(s, x)| s / x.max(1e-300))
        .collect();
    // compared bins: coherent, and carrying input power (a sweep leaves the bins above
    // its last frequency empty, where coherence means nothing)
    let input_peak = sxx.iter().copied().fold(0.0, f64::max);
    let driven: Vec<bool> = sxx.iter().map(|x| *x > INPUT_POWER * input_peak).collect();
    let coherent = (0..freq.len())
        .map(|k| driven[k] && sxy_m[k].norm_sqr() / (sxx[k] * syy_m[k]).max(1e-300) > COHERENCE)
        .collect();
    Response {
        measured_db: hm.iter().map(|h| db(*h)).collect(),
        simulated_db: hs.iter().map(|h| db(*h)).collect(),
        measured_deg: hm.iter().map(|h| deg(*h)).collect(),
        simulated_deg: hs.iter().map(|h| deg(*h)).collect(),
        freq,
        coherent,
        driven,
    }
}

pub fn localise(
    m: &Measured,
    e: &Experiment,
    sim: &Traces,
    noise: &[(&'static str, f64)],
) -> Localisation {
    let signals = noise
        .iter()
        .filter_map(|(name, sigma)| {
            let (a, b) = (m.get(name)?, sim.get(name)?);
            let d: Vec<f64> = a.iter().zip(b).map(|(a, b)| a - b).collect();
            let n = d.len().max(1) as f64;
            Some(SignalGap {
                signal: name.to_string(),
                rms: (d.iter().map(|x| x * x).sum::<f64>() / n).sqrt(),
                noise: *sigma,
                offset: d.iter().sum::<f64>() / n,
            })
        })
        .collect();
    let n = m.time.len();
    let windows: Vec<WindowGap> = (0..WINDOWS)
        .map(|w| {
            let Range { start: a, end: b } = window(w, n);
            let mut s = 0.0;
            let mut count = 0;
            for (name, sigma) in noise {
                if let (Some(x), Some(y)) = (m.get(name), sim.get(name)) {
                    for k in a..b {
                        s += ((x[k] - y[k]) / sigma).powi(2);
                        count += 1;
                    }
                }
            }
            WindowGap {
                start: m.time[a],
                end: m.time[b - 1],
                gap: (s / count.max(1) as f64).sqrt(),
            }
        })
        .collect();
    let oscillation = oscillation_in_worst(m, sim, &windows, noise);
    let input_name = match &e.drive {
        Drive::Proportional { reference, .. } => reference.as_str(),
        Drive::OpenLoop => "u1",
    };
    let input = m.get(input_name);
    let response = input
        .filter(|x| x.len() >= 256)
        .map(|x| response(m, sim, x));
    let (resonance, pressure_resonance) =
        resonances(m, sim, input_name, matches!(e.drive, Drive::OpenLoop));
    let (mut bands, mut delay) = (Vec::new(), None);
    if let Some(r) = &response {
        let ratio = |k: usize| {
            (
                r.measured_db[k] - r.simulated_db[k],
                wrap(r.measured_deg[k] - r.simulated_deg[k]),
            )
        };
        for [lo, hi] in BANDS {
            let ks: Vec<usize> = (0..r.freq.len())
                .filter(|&k| r.coherent[k] && r.freq[k] >= lo && r.freq[k] < hi)
                .collect();
            if ks.is_empty() {
                continue;
            }
            let (g, p) = ks.iter().fold((0.0, 0.0), |(g, p), &k| {
                let (dg, dp) = ratio(k);
                (g + dg, p + dp)
            });
            bands.push(BandGap {
                low_hz: lo,
                high_hz: hi,
                gain_db: g / ks.len() as f64,
                phase_deg: p / ks.len() as f64,
                bins: ks.len(),
            });
        }
        let ok = &r.coherent;
        // least-squares slope of the phase difference against omega through the origin
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for k in (0..r.freq.len()).filter(|&k| ok[k] && r.freq[k] > 0.0) {
            let w = 2.0 * PI * r.freq[k];
            sxy += w * ratio(k).1.to_radians();
            sxx += w * w;
        }
        if sxx > 0.0 {
            delay = Some(-sxy / sxx);
        }
    }
    Localisation {
        signals,
        windows,
        bands,
        resonance,
        pressure_resonance,
        equivalent_delay: delay,
        oscillation,
        response,
    }
}

/// `oscillation::find` in the window of largest disagreement, against the noise of the
/// signal it reads (P1 - P2: both sensors' noise; y: the position sensor's).
fn oscillation_in_worst(
    m: &Measured,
    sim: &Traces,
    windows: &[WindowGap],
    noise: &[(&'static str, f64)],
) -> Option<Oscillation> {
    let worst = (0..windows.len()).max_by(|a, b| windows[*a].gap.total_cmp(&windows[*b].gap))?;
    let range = window(worst, m.time.len());
    let sigma = |name: &str| noise.iter().find(|(s, _)| *s == name).map(|(_, v)| *v);
    let load = sigma("P1")
        .zip(sigma("P2"))
        .map(|(a, b)| a.hypot(b))
        .or_else(|| sigma("y"))?;
    super::oscillation::find(m, sim, range, load)
}

/// The samples of time window `w` of WINDOWS over a record of `n` samples.
fn window(w: usize, n: usize) -> Range<usize> {
    w * n / WINDOWS..((w + 1) * n / WINDOWS).min(n)
}

fn wrap(deg: f64) -> f64 {
    (deg + 180.0).rem_euclid(360.0) - 180.0
}

/// The disagreement in words.
pub fn describe(l: &Localisation) -> Vec<String> {
    let mut s = Vec::new();
    for g in &l.signals {
        let (unit, f) = if g.signal == "y" {
            ("um", 1e6)
        } else {
            ("bar", 1e-5)
        };
        s.push(format!(
            "{}: RMS difference {:.3} {unit} = {:.1} x its noise ({:.3} {unit}); mean offset {:+.3} {unit}",
            g.signal,
            g.rms * f,
            g.rms / g.noise,
            g.noise * f,
            g.offset * f
        ));
    }
    if let Some(w) = l.windows.iter().max_by(|a, b| a.gap.total_cmp(&b.gap)) {
        s.push(format!(
            "largest disagreement in {:.2}-{:.2} s ({:.1} x noise)",
            w.start, w.end, w.gap
        ));
    }
    for b in &l.bands {
        s.push(format!(
            "{:.0}-{:.0} Hz: measured/simulated gain {:+.2} dB, phase {:+.1} deg ({} bins)",
            b.low_hz, b.high_hz, b.gain_db, b.phase_deg, b.bins
        ));
    }
    for r in l.resonance.iter().chain(&l.pressure_resonance) {
        s.push(format!(
            "resonance of {}: measured {:.1} Hz (damping {:.3}), simulated {:.1} Hz (damping {:.3})",
            r.response, r.measured_hz, r.measured_damping, r.simulated_hz, r.simulated_damping
        ));
    }
    if let Some(o) = &l.oscillation {
        let (unit, f) = if o.signal == "y" {
            ("um", 1e6)
        } else {
            ("bar", 1e-5)
        };
        s.push(format!(
            "{} oscillates at {:.0} Hz in {:.2}-{:.2} s: measured {:.3} {unit} RMS, simulated {:.3} {unit} \
             (the sinusoid holds {:.0} % of the residual there): an oscillation the model does not have; \
             a fit in time cannot follow a self-excited oscillation's phase",
            o.signal,
            o.frequency_hz,
            o.start,
            o.end,
            o.measured_rms * f,
            o.simulated_rms * f,
            100.0 * o.share
        ));
    }
    if let Some(d) = l.equivalent_delay {
        s.push(format!(
            "phase difference equivalent to a delay of {:.3} ms",
            d * 1e3
        ));
    }
    s
}
