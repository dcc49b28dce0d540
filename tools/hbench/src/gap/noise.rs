//! The noise floor of a measured signal, read from the data alone (minimum statistics
//! over short segments): the unit in which every gap is counted.

use rustfft::{num_complex::Complex, FftPlanner};

use super::resonance::hann;

/// Noise standard deviation of a sampled signal, estimated from the data alone by
/// minimum statistics: white noise spreads its power evenly over all frequencies, while
/// what the bench does (moves, sweeps, ringing resonances) fills only part of the band,
/// so the lower fifth of the bins of a periodogram holds only noise.
///
/// Two passes over short Hann segments. First each segment's own estimate (its bins'
/// order statistic against that of unit exponentials, the law of a white periodogram
/// bin) and a low quantile over the segments give a rough level that holds as long as a
/// quarter of the segments are quiet; segments far above it, where a transient such as a
/// step's ringing fills the whole band, are set aside. Then the spectra of the others are
/// averaged (Welch) and their lower fifth read as the noise, corrected for the
/// chi-square spread of the averaged bins. Averaging every segment, transients included,
/// read the 0.13 bar pressure noise of the steps experiment as 1.07 bar (measured).
/// Segments whose converter is stuck (saturated sensor) carry no noise and are skipped.
/// Floored at the quantisation noise.
///
/// The Welch average assumes that what the bench does sits in the same bins of every
/// quiet segment. A record whose drive sweeps in frequency breaks that: each segment's
/// signal fills other bins, and the average fills bins no segment fills. On the 2.5 s
/// closed-loop sweep it read the 0.13 bar pressure noise 1.25-1.93 times too high, on the
/// chirp up to 1.26 times (both benches, form error, nothing or an effect hidden; against
/// the noise `hide` added). So the segments are read on their own as well
/// (`Readings::segments`), and where the Welch reading exceeds theirs by more than it
/// does on pure noise the segments' is taken (`Readings::chosen`): the sweeps' pressures
/// then read 1.03-1.25 times the truth. The steps and moves of both benches keep the
/// Welch reading, and so do 97.5-99.5 % of white-noise records.
pub fn noise(x: &[f64], quantum: f64) -> f64 {
    let floor = quantum / 12f64.sqrt();
    readings(x).map_or(floor, |r| r.chosen().sqrt().max(floor))
}

/// The two readings of a signal's noise variance.
#[derive(Debug, Clone, Copy)]
struct Readings {
    /// The Welch average of the quiet segments, its lower fifth.
    welch: f64,
    /// The segments' own estimates, their lower part (`segments_estimate`).
    segments: f64,
    /// How many segments were read.
    count: usize,
}

impl Readings {
    /// The Welch reading, unless it exceeds the segments' by more than it does on pure
    /// noise: there the ratio of the two (in standard deviation) sits at 1 +
    /// `NOISE_RATIO_BIAS` / sqrt(m) and spreads by `NOISE_RATIO_SPREAD` / sqrt(m).
    fn chosen(&self) -> f64 {
        let beyond = (NOISE_RATIO_BIAS + NOISE_SWITCH_SPREADS * NOISE_RATIO_SPREAD)
            / (self.count as f64).sqrt();
        if (self.welch / self.segments).sqrt() > 1.0 + beyond {
            self.segments
        } else {
            self.welch
        }
    }
}

/// Both readings of the noise variance of `x`; None when it holds fewer than two segments
/// or every segment is stuck.
fn readings(x: &[f64]) -> Option<Readings> {
    let n = NOISE_SEGMENT;
    if x.len() < 2 * n {
        return None;
    }
    let fft = FftPlanner::new().plan_fft_forward(n);
    let hann = hann(n);
    let w2: f64 = hann.iter().map(|w| w * w).sum();
    // bins 1..n/2: the mean removal empties bin 0
    let bins = n / 2 - 1;
    let rank = (NOISE_QUANTILE * bins as f64) as usize;
    let lower = |psd: &[f64]| {
        let mut v = psd.to_vec();
        v.select_nth_unstable_by(rank, f64::total_cmp);
        v[rank]
    };
    let spectra: Vec<Vec<f64>> = x
        .windows(n)
        .step_by(n / 2)
        .filter(|s| {
            let stuck = s.windows(2).filter(|w| w[0] == w[1]).count();
            stuck as f64 <= NOISE_STUCK_FRACTION * n as f64
        })
        .map(|s| {
            let mean = s.iter().sum::<f64>() / n as f64;
            let mut b: Vec<Complex<f64>> = s
                .iter()
                .zip(&hann)
                .map(|(v, w)| Complex::new((v - mean) * w, 0.0))
                .collect();
            fft.process(&mut b);
            b[1..=bins].iter().map(|c| c.norm_sqr() / w2).collect()
        })
        .collect();
    if spectra.is_empty() {
        return None;
    }
    // pass 1: Renyi, the (rank+1)-th smallest of `bins` unit exponentials is a sum of
    // independent exponentials of means 1/(bins-i), close to a gamma law
    let expected: f64 = (0..=rank).map(|i| 1.0 / (bins - i) as f64).sum();
    let variance: f64 = (0..=rank).map(|i| 1.0 / ((bins - i) as f64).powi(2)).sum();
    let own: Vec<f64> = spectra.iter().map(|p| lower(p) / expected).collect();
    let mut sorted = own.clone();
    sorted.sort_by(f64::total_cmp);
    let m = sorted.len();
    let shape = expected.powi(2) / variance;
    let k = ((NOISE_SEGMENT_QUANTILE * (m + 1) as f64).round() as usize).clamp(1, m);
    let rough = rank_read(&sorted, k - 1, shape);
    // pass 2: Welch over the quiet segments
    let quiet: Vec<&Vec<f64>> = spectra
        .iter()
        .zip(&own)
        .filter(|(_, e)| **e <= NOISE_TRANSIENT_RATIO * rough)
        .map(|(p, _)| p)
        .collect();
    let mut psd = vec![0.0; bins];
    for p in &quiet {
        psd.iter_mut().zip(p.iter()).for_each(|(a, b)| *a += b);
    }
    psd.iter_mut().for_each(|a| *a /= quiet.len() as f64);
    psd.sort_by(f64::total_cmp);
    let q = psd[rank];
    // chi2(nu)/nu with nu = 2 per segment less the Hann overlap's correlation (about
    // 10 %), approximated by a gamma law of shape nu/2
    let nu = 1.8 * quiet.len() as f64;
    Some(Readings {
        welch: q / gamma_quantile(NOISE_QUANTILE, nu / 2.0),
        segments: segments_estimate(&sorted, shape),
        count: m,
    })
}

/// The noise variance read from the segments' own estimates `sorted` (ascending, each of
/// mean 1 times the variance on pure noise, of a gamma law of shape `shape`): each of the
/// lower `NOISE_SEGMENTS_LOWER` of them over the quantile its rank has under that law,
/// averaged. Segments the bench's signal fills sit above the others, so the lower part is
/// read, and several order statistics are averaged for a steadier figure than one.
fn segments_estimate(sorted: &[f64], shape: f64) -> f64 {
    let m = sorted.len();
    let lower = ((NOISE_SEGMENTS_LOWER * m as f64) as usize).clamp(1, m);
    (0..lower).map(|i| rank_read(sorted, i, shape)).sum::<f64>() / lower as f64
}

/// The variance read from `sorted[i]`, the (i+1)-th smallest of the m segments'
/// estimates: on average it sits at quantile (i+1)/(m+1) of their gamma law of `shape`.
fn rank_read(sorted: &[f64], i: usize, shape: f64) -> f64 {
    sorted[i] / gamma_quantile((i + 1) as f64 / (sorted.len() + 1) as f64, shape)
}

/// Segment of the noise estimate: 128 samples (0.128 s at 1 kHz), overlapping by half,
/// gives 63 bins per segment and about 16 segments per second of data.
const NOISE_SEGMENT: usize = 128;
/// Quantile of the bins taken as noise-only.
const NOISE_QUANTILE: f64 = 0.2;
/// Quantile over the segments of the rough level: a quarter of them must be free of
/// broadband transients (the steps experiment has two of about 50 ms in 0.65 s, which
/// touch 4 of its 9 segments).
const NOISE_SEGMENT_QUANTILE: f64 = 0.25;
/// A segment whose own estimate exceeds the rough level by this factor (in variance) holds
/// a transient: a quiet segment's estimate spreads by about 30 % (measured on white
/// noise), so 3 lies several spreads above it.
const NOISE_TRANSIENT_RATIO: f64 = 3.0;
/// A segment in which more than this share of samples repeat the one before comes from a
/// saturated converter (white noise of 0.13 bar repeats a 3 mbar step about 1 % of the
/// time, the LVDT's 30 um a 4.6 um step about 4 %).
const NOISE_STUCK_FRACTION: f64 = 0.25;
/// Share of the segments, the quietest, whose own estimates the segments' reading takes
/// (`segments_estimate`): 0.4 leaves it right while up to 60 % of the segments are
/// filled by the bench's signal, and averages enough of them to spread 3.5 % on 2.5 s of
/// white noise (against 3.7 % for the one quantile `NOISE_SEGMENT_QUANTILE`; measured
/// with scipy's gamma law).
const NOISE_SEGMENTS_LOWER: f64 = 0.4;
/// On white noise the ratio of the Welch reading to the segments' (in standard deviation)
/// sits above 1 by this over the square root of the number of segments m, and spreads by
/// `NOISE_RATIO_SPREAD` over it: measured on 400 records of each length, m = 9, 14, 30, 38,
/// 155 (0.65 s to 10 s), the ratio's mean less 1 times sqrt(m) was 0.13, 0.13, 0.13, 0.15,
/// 0.21 and its spread times sqrt(m) 0.23, 0.22, 0.22, 0.20, 0.21 (the segments' reading
/// sits a little low: the Hann window correlates neighbouring bins, which the gamma law of
/// its order statistics leaves out).
const NOISE_RATIO_BIAS: f64 = 0.13;
const NOISE_RATIO_SPREAD: f64 = 0.22;
/// How many spreads the ratio must exceed its pure-noise value by before the segments'
/// reading is taken: 2.5 (one-sided, 0.6 % of a normal law; 0.5-2.5 % of white-noise
/// records switched, measured on 400 of each length), so only a record whose segments
/// disagree with the average takes the less precise reading.
const NOISE_SWITCH_SPREADS: f64 = 2.5;

/// Quantile p of a gamma law of mean 1 and shape `shape` (Wilson-Hilferty).
fn gamma_quantile(p: f64, shape: f64) -> f64 {
    let c = 1.0 / (9.0 * shape);
    (1.0 - c + normal_quantile(p) * c.sqrt()).powi(3)
}

/// Standard normal quantile, Abramowitz and Stegun 26.2.23 (error below 4.5e-4).
fn normal_quantile(p: f64) -> f64 {
    let tail = |q: f64| {
        let t = (-2.0 * q.ln()).sqrt();
        t - (2.515517 + 0.802853 * t + 0.010328 * t * t)
            / (1.0 + 1.432788 * t + 0.189269 * t * t + 0.001308 * t * t * t)
    };
    if p < 0.5 {
        -tail(p)
    } else {
        tail(1.0 - p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gap::analysis::quantum;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use std::f64::consts::PI;

    #[test]
    fn noise_estimate_sees_through_fast_signals() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let sigma = 0.13e5;
        let n = Normal::new(0.0, sigma).unwrap();
        // a pressure swinging 20 bar at up to 200 Hz over a log chirp, plus noise
        let x: Vec<f64> = (0..2500)
            .map(|k| {
                let t = k as f64 * 1e-3;
                let phase = 2.0 * PI * 2.0 * ((t * (100f64).ln() / 2.5).exp() - 1.0)
                    / ((100f64).ln() / 2.5);
                100e5 + 20e5 * phase.sin() + n.sample(&mut rng)
            })
            .collect();
        let est = noise(&x, quantum("P1"));
        assert!((est / sigma - 1.0).abs() < 0.1, "{est} against {sigma}");
        // white noise alone, and a slow signal with it
        let white: Vec<f64> = (0..2500).map(|_| n.sample(&mut rng)).collect();
        let est = noise(&white, quantum("P1"));
        assert!(
            (est / sigma - 1.0).abs() < 0.1,
            "white: {est} against {sigma}"
        );
    }

    #[test]
    fn noise_estimate_sees_through_ringing_transients() {
        // the steps experiment: a quiet pressure with two 50 ms bursts ringing at 300 Hz,
        // 5 bar, that fill every bin of the segments they touch
        let mut rng = rand_pcg::Pcg64::seed_from_u64(8);
        let sigma = 0.13e5;
        let n = Normal::new(0.0, sigma).unwrap();
        let x: Vec<f64> = (0..650)
            .map(|k| {
                let t = k as f64 * 1e-3;
                let burst = |t0: f64| {
                    if t >= t0 {
                        7e5 * (-(t - t0) / 0.01).exp() * (2.0 * PI * 300.0 * (t - t0)).sin()
                    } else {
                        0.0
                    }
                };
                106e5 + burst(0.05) + burst(0.35) + n.sample(&mut rng)
            })
            .collect();
        let est = noise(&x, quantum("P1"));
        assert!((est / sigma - 1.0).abs() < 0.15, "{est} against {sigma}");
        // a saturated stretch carries no noise and is not read as quiet
        let mut y = x.clone();
        y[100..400].iter_mut().for_each(|v| *v = 206e5);
        let est = noise(&y, quantum("P1"));
        assert!((est / sigma - 1.0).abs() < 0.15, "saturated: {est}");
    }

    #[test]
    fn noise_estimate_of_a_sweeping_record_reads_the_noise_added() {
        // section 4.4's model under the closed-loop sweep, with the noise and the
        // quantisation `hide` adds: the Welch reading fills with the sweep's bins
        use crate::gap::experiments::Kind;
        let truth = hbmodel::sensors::SensorParams::default().pressure_noise;
        let model = crate::gap::variants::section_4_4();
        let mut welch_worst: f64 = 0.0;
        for seed in 1..=3 {
            let (_, m) = crate::gap::hide::measure(&model, Kind::Sweep, seed).expect("a sweep");
            for s in ["P1", "P2"] {
                let x = m.get(s).expect("pressures");
                let r = readings(x).expect("segments");
                welch_worst = welch_worst.max(r.welch.sqrt() / truth);
                let read = noise(x, quantum(s)) / truth;
                assert!((0.9..1.3).contains(&read), "{s}, seed {seed}: {read}");
            }
        }
        assert!(welch_worst > 1.3, "the Welch reading alone: {welch_worst}");
        // where the bench's signal stays in its bins, the Welch reading is kept
        for kind in [Kind::Steps, Kind::Moves] {
            for seed in 1..=2 {
                let (_, m) = crate::gap::hide::measure(&model, kind, seed).expect("a record");
                for s in ["y", "P1", "P2"] {
                    let r = readings(m.get(s).expect("a signal")).expect("segments");
                    assert_eq!(r.chosen(), r.welch, "{s}, {kind:?}, seed {seed}");
                }
            }
        }
    }
}
