//! Measurement chain of the bench: sensors, analog conditioning and the dSPACE DS1104
//! acquisition (thesis lines 913-935 and 5708-5712: "digitalized at a sampling rate of
//! 1 kHz with 16 bits precision"). Turns a simulated (true) trajectory into samples
//! that look like the recorded ones: sampled, delayed, noisy and quantised.
//!
//! Order inside one sample: the analog signal carries the sensor noise *before* the ADC,
//! so noise is added first and the sum is then clamped and quantised; every output is an
//! ADC code, as in the recorded files.

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// s, DS1104 sampling period at 1 kHz (line 5711).
pub const DEFAULT_SAMPLE_PERIOD: f64 = 1.0e-3;

/// s, the "time delay of 0.5 ms in the digital control" due to 1 kHz sampling, quoted as
/// about 18 deg of phase at 100 Hz (line 6201).
pub const DEFAULT_DELAY: f64 = 0.5e-3;

/// m, LVDT measuring range (line 919, Table 1.1).
pub const LVDT_SPAN: f64 = 0.3;

/// m, std dev of the LVDT noise. The thesis's "0.1 % of the measuring range" (0.3 mm, line
/// 920 and line 8040 "linearity error of 0.3 mm") is a linearity class, a systematic
/// error, not noise. One tenth of it, 0.01 % of the span, is 30 um: this matches the
/// steady-state position-error STD of 32-41 um that Tables 5.1 and 6.1 report for five
/// very different controllers, a floor that only the measurement can set.
pub const DEFAULT_POSITION_NOISE: f64 = 0.1 * 1.0e-3 * LVDT_SPAN;

/// Pa, peak amplitude of the chamber-pressure noise: "noise level with an amplitude up to
/// 0.4 bar" (line 9543).
pub const PRESSURE_NOISE_PEAK: f64 = 0.4e5;

/// Pa, std dev of the pressure noise: the 0.4 bar peak read as a 3-sigma bound.
pub const DEFAULT_PRESSURE_NOISE: f64 = PRESSURE_NOISE_PEAK / 3.0;

/// DS1104 converter resolution (line 5711).
pub const DEFAULT_ADC_BITS: u32 = 16;

/// m, LVDT span centred on mid-stroke, which is the position origin of the model.
pub const DEFAULT_POSITION_RANGE: [f64; 2] = [-0.5 * LVDT_SPAN, 0.5 * LVDT_SPAN];

/// Pa, chamber pressure sensors "operating range of 0 to 206 bar" (line 925).
pub const DEFAULT_PRESSURE_RANGE: [f64; 2] = [0.0, 206.0e5];

/// Range of [`Channel::Exact`]: the +-10 V span of the DS1104 converters, which carry
/// the servovalve commands (rated input +-10 V). Values outside it are clamped.
pub const EXACT_RANGE: [f64; 2] = [-10.0, 10.0];

/// Any fixed value makes runs reproducible; this one spells "SEED".
pub const DEFAULT_SEED: u64 = 0x5345_4544;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorParams {
    /// s, acquisition period.
    pub sample_period: f64,
    /// s, delay between the physical value and its sample.
    pub delay: f64,
    /// m, std dev of the LVDT noise.
    pub position_noise: f64,
    /// Pa, std dev of the chamber-pressure noise.
    pub pressure_noise: f64,
    /// ADC resolution; the codes span the channel range.
    pub adc_bits: u32,
    /// m, LVDT span mapped onto the ADC.
    pub position_range: [f64; 2],
    /// Pa, pressure-sensor span mapped onto the ADC.
    pub pressure_range: [f64; 2],
    /// Seed of every noise stream.
    pub seed: u64,
}

impl Default for SensorParams {
    fn default() -> Self {
        Self {
            sample_period: DEFAULT_SAMPLE_PERIOD,
            delay: DEFAULT_DELAY,
            position_noise: DEFAULT_POSITION_NOISE,
            pressure_noise: DEFAULT_PRESSURE_NOISE,
            adc_bits: DEFAULT_ADC_BITS,
            position_range: DEFAULT_POSITION_RANGE,
            pressure_range: DEFAULT_PRESSURE_RANGE,
            seed: DEFAULT_SEED,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Error)]
pub enum SensorError {
    #[error("sensor parameter `{name}` = {value} {requirement}")]
    Invalid {
        name: &'static str,
        value: f64,
        requirement: &'static str,
    },
}

/// Quantisation beyond the f64 mantissa would be a no-op with rounding artefacts.
const MAX_ADC_BITS: u32 = 52;

impl SensorParams {
    /// Checks the conditions [`Sensor::new`] and [`sample_trajectory`] rely on.
    pub fn validate(&self) -> Result<(), SensorError> {
        let check = |name, value: f64, ok: bool, requirement| {
            if ok && value.is_finite() {
                Ok(())
            } else {
                Err(SensorError::Invalid {
                    name,
                    value,
                    requirement,
                })
            }
        };
        check(
            "sample_period",
            self.sample_period,
            self.sample_period > 0.0,
            "must be > 0",
        )?;
        check("delay", self.delay, self.delay >= 0.0, "must be >= 0")?;
        check(
            "position_noise",
            self.position_noise,
            self.position_noise >= 0.0,
            "must be >= 0",
        )?;
        check(
            "pressure_noise",
            self.pressure_noise,
            self.pressure_noise >= 0.0,
            "must be >= 0",
        )?;
        check(
            "adc_bits",
            f64::from(self.adc_bits),
            (1..=MAX_ADC_BITS).contains(&self.adc_bits),
            "must be in 1..=52",
        )?;
        let [lo, hi] = self.position_range;
        check("position_range[0]", lo, lo.is_finite(), "must be finite")?;
        check(
            "position_range[1]",
            hi,
            hi > lo,
            "must exceed position_range[0]",
        )?;
        let [lo, hi] = self.pressure_range;
        check("pressure_range[0]", lo, lo.is_finite(), "must be finite")?;
        check(
            "pressure_range[1]",
            hi,
            hi > lo,
            "must exceed pressure_range[0]",
        )
    }
}

/// One channel kind decides noise and range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channel {
    /// LVDT piston position, m.
    Position,
    /// Chamber pressure sensor, Pa.
    Pressure,
    /// Noise-free acquisition over [`EXACT_RANGE`] (e.g. commands in V).
    Exact,
}

/// One acquisition channel; owns its noise stream so channels are independent and
/// reproducible.
#[derive(Debug, Clone)]
pub struct Sensor {
    channel: Channel,
    range: [f64; 2],
    step: f64,
    codes: f64,
    noise: Option<Normal<f64>>,
    rng: Pcg64,
}

impl Sensor {
    /// `stream` distinguishes channels sharing `params.seed` (e.g. P1 and P2).
    ///
    /// # Panics
    /// If `params` fails [`SensorParams::validate`].
    pub fn new(params: &SensorParams, channel: Channel, stream: u64) -> Self {
        if let Err(e) = params.validate() {
            panic!("invalid SensorParams: {e}");
        }
        let (range, sigma) = match channel {
            Channel::Position => (params.position_range, params.position_noise),
            Channel::Pressure => (params.pressure_range, params.pressure_noise),
            Channel::Exact => (EXACT_RANGE, 0.0),
        };
        let codes = 2f64.powi(params.adc_bits as i32);
        let noise = (sigma > 0.0).then(|| Normal::new(0.0, sigma).expect("validated std dev"));
        Self {
            channel,
            range,
            step: (range[1] - range[0]) / codes,
            codes,
            noise,
            rng: Pcg64::from_seed(pcg_seed(params.seed, stream)),
        }
    }

    pub fn channel(&self) -> Channel {
        self.channel
    }

    /// [lo, hi] mapped onto the ADC codes.
    pub fn range(&self) -> [f64; 2] {
        self.range
    }

    /// One LSB: range / 2^adc_bits.
    pub fn quantisation_step(&self) -> f64 {
        self.step
    }

    /// Quantise to adc_bits over the channel range (clamped to range), add Gaussian noise (rand_distr::Normal).
    ///
    /// The noise enters before the converter (see the module notes), so the result is
    /// always `lo + k * step` with `0 <= k < 2^adc_bits`, rounded to the nearest code.
    /// NaN propagates.
    pub fn measure(&mut self, true_value: f64) -> f64 {
        let analog = match &self.noise {
            Some(n) => true_value + n.sample(&mut self.rng),
            None => true_value,
        };
        let [lo, _] = self.range;
        // A real converter saturates at its extreme codes; the top code is hi - step.
        let code = ((analog - lo) / self.step)
            .round()
            .clamp(0.0, self.codes - 1.0);
        lo + code * self.step
    }
}

/// SplitMix64 step: spreads (seed, stream) over the whole 256-bit PCG seed so that nearby
/// seeds or streams give unrelated sequences (PCG streams with equal state are correlated).
fn splitmix64(x: &mut u64) -> u64 {
    *x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *x;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn pcg_seed(seed: u64, stream: u64) -> [u8; 32] {
    let mut stream_state = stream;
    let mut state = seed ^ splitmix64(&mut stream_state);
    let mut out = [0u8; 32];
    for chunk in out.chunks_exact_mut(8) {
        chunk.copy_from_slice(&splitmix64(&mut state).to_le_bytes());
    }
    out
}

/// Offline: given a dense true trajectory (times strictly increasing, values), return the measured samples at
/// t_k = k*sample_period (k=0.. while t_k <= last time): value interpolated linearly at t_k - delay (held at the first value before the start), then measure().
///
/// Returns `(t_k, measured_k)`. An empty trajectory gives no samples.
///
/// # Panics
/// If `times` and `values` differ in length or `params` is invalid.
pub fn sample_trajectory(
    params: &SensorParams,
    channel: Channel,
    stream: u64,
    times: &[f64],
    values: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    assert_eq!(
        times.len(),
        values.len(),
        "times and values must have the same length"
    );
    let mut sensor = Sensor::new(params, channel, stream);
    let Some(&t_last) = times.last() else {
        return (Vec::new(), Vec::new());
    };
    let period = params.sample_period;
    // t_k is computed as k * T, not accumulated, so k * T that should equal t_last may land
    // one ulp above it; the tolerance keeps that last sample.
    let t_end = t_last + 1e-9 * period;
    let mut t_out = Vec::new();
    let mut y_out = Vec::new();
    let mut k: u32 = 0;
    let mut seg = 0;
    loop {
        let t_k = f64::from(k) * period;
        if t_k > t_end {
            break;
        }
        let t_seen = t_k - params.delay;
        // Queries are non-decreasing, so the segment index only moves forward.
        while seg + 1 < times.len() && times[seg + 1] <= t_seen {
            seg += 1;
        }
        let truth = interpolate(times, values, seg, t_seen);
        t_out.push(t_k);
        y_out.push(sensor.measure(truth));
        k += 1;
    }
    (t_out, y_out)
}

/// Linear interpolation on segment `seg` (times[seg] <= t < times[seg+1]), holding the end
/// values outside the data.
fn interpolate(times: &[f64], values: &[f64], seg: usize, t: f64) -> f64 {
    if t <= times[0] {
        return values[0];
    }
    if seg + 1 >= times.len() {
        return values[seg];
    }
    let (t0, t1) = (times[seg], times[seg + 1]);
    let w = (t - t0) / (t1 - t0);
    values[seg] + w * (values[seg + 1] - values[seg])
}

/// Zero-order hold: value of a sampled signal (t_k, y_k) at time t (last sample at or before t).
///
/// Before the first sample the first value is held, as [`sample_trajectory`] does.
///
/// # Panics
/// If the slices are empty or differ in length.
pub fn zero_order_hold(t_samples: &[f64], y_samples: &[f64], t: f64) -> f64 {
    assert_eq!(
        t_samples.len(),
        y_samples.len(),
        "t_samples and y_samples must have the same length"
    );
    assert!(!t_samples.is_empty(), "zero_order_hold needs samples");
    let after = t_samples.partition_point(|&tk| tk <= t);
    y_samples[after.saturating_sub(1)]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn std_dev(x: &[f64]) -> f64 {
        let n = x.len() as f64;
        let mean = x.iter().sum::<f64>() / n;
        (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    }

    fn measure_n(params: &SensorParams, channel: Channel, stream: u64, value: f64) -> Vec<f64> {
        let mut s = Sensor::new(params, channel, stream);
        (0..20_000).map(|_| s.measure(value)).collect()
    }

    #[test]
    fn defaults_are_valid() {
        SensorParams::default().validate().unwrap();
        let bad = SensorParams {
            adc_bits: 0,
            ..SensorParams::default()
        };
        assert!(bad.validate().is_err());
    }

    #[test]
    fn same_seed_same_output_other_seed_or_stream_differs() {
        let p = SensorParams::default();
        let a = measure_n(&p, Channel::Position, 0, 0.01);
        assert_eq!(a, measure_n(&p, Channel::Position, 0, 0.01));
        let other_seed = SensorParams {
            seed: p.seed + 1,
            ..p.clone()
        };
        assert_ne!(a, measure_n(&other_seed, Channel::Position, 0, 0.01));
        assert_ne!(a, measure_n(&p, Channel::Position, 1, 0.01));
    }

    #[test]
    fn clone_continues_the_same_stream() {
        let mut s = Sensor::new(&SensorParams::default(), Channel::Pressure, 3);
        s.measure(50e5);
        let mut c = s.clone();
        assert_eq!(s.measure(50e5), c.measure(50e5));
    }

    #[test]
    fn noise_std_matches_parameter() {
        let p = SensorParams::default();
        for (channel, value, sigma) in [
            (Channel::Position, 0.0123, p.position_noise),
            (Channel::Pressure, 100e5, p.pressure_noise),
        ] {
            let y = measure_n(&p, channel, 7, value);
            let s = std_dev(&y);
            assert!(
                (s / sigma - 1.0).abs() < 0.1,
                "{channel:?}: std {s} vs {sigma}"
            );
            let mean = y.iter().sum::<f64>() / y.len() as f64;
            assert!((mean - value).abs() < 5.0 * sigma / (y.len() as f64).sqrt() + sigma * 0.01);
        }
        let exact = measure_n(&p, Channel::Exact, 7, 1.234);
        assert!(exact.iter().all(|&v| v == exact[0]));
    }

    #[test]
    fn quantisation_step_is_range_over_two_to_the_bits() {
        let p = SensorParams {
            position_noise: 0.0,
            ..SensorParams::default()
        };
        let mut s = Sensor::new(&p, Channel::Position, 0);
        let [lo, hi] = p.position_range;
        let q = (hi - lo) / 65536.0;
        assert_eq!(s.quantisation_step(), q);
        let mut levels: Vec<f64> = (0..5000)
            .map(|i| s.measure(0.01 + f64::from(i) * 1e-7))
            .collect();
        for &y in &levels {
            let k = (y - lo) / q;
            assert!((k - k.round()).abs() < 1e-6, "{y} is not on the ADC grid");
        }
        levels.dedup();
        let min_step = levels
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::INFINITY, f64::min);
        assert!((min_step / q - 1.0).abs() < 1e-6);
        // Zero lies on a code: no offset at mid-stroke.
        assert_eq!(s.measure(0.0), 0.0);
    }

    #[test]
    fn out_of_range_values_saturate() {
        let p = SensorParams::default();
        let mut s = Sensor::new(&p, Channel::Pressure, 0);
        assert_eq!(s.measure(-50e5), 0.0);
        let top = s.measure(400e5);
        assert_eq!(top, p.pressure_range[1] - s.quantisation_step());
        assert_eq!(s.measure(f64::INFINITY), top);
        let mut e = Sensor::new(&p, Channel::Exact, 0);
        assert_eq!(e.measure(-20.0), EXACT_RANGE[0]);
    }

    #[test]
    fn delayed_ramp_lags_by_exactly_the_delay() {
        let p = SensorParams {
            adc_bits: 40,
            ..SensorParams::default()
        };
        // Dense truth on a grid unrelated to the sample period, starting at 0.3 ms.
        let times: Vec<f64> = (0..=2000).map(|i| 0.3e-3 + f64::from(i) * 37e-6).collect();
        let values: Vec<f64> = times.iter().map(|t| 2.0 * t).collect();
        let (tk, yk) = sample_trajectory(&p, Channel::Exact, 0, &times, &values);
        let t_last = *times.last().unwrap();
        assert_eq!(tk.len(), (t_last / p.sample_period).floor() as usize + 1);
        let q = Sensor::new(&p, Channel::Exact, 0).quantisation_step();
        for (t, y) in tk.iter().zip(&yk) {
            let expected = 2.0 * (t - p.delay).max(times[0]);
            assert!((y - expected).abs() <= q, "t={t}: {y} vs {expected}");
        }
        // Sample 0 (t = 0) precedes the data and holds its first value.
        assert!((yk[0] - values[0]).abs() <= q);
    }

    #[test]
    fn last_sample_on_the_final_time_is_kept() {
        let p = SensorParams::default();
        let times: Vec<f64> = (0..=100).map(|i| f64::from(i) * 1e-3).collect();
        let values = vec![1.0; times.len()];
        let (tk, yk) = sample_trajectory(&p, Channel::Exact, 0, &times, &values);
        assert_eq!(tk.len(), 101);
        assert_eq!(yk.len(), 101);
        let empty = sample_trajectory(&p, Channel::Exact, 0, &[], &[]);
        assert!(empty.0.is_empty() && empty.1.is_empty());
    }

    #[test]
    fn zoh_holds_the_previous_sample() {
        let t = [0.0, 1e-3, 2e-3];
        let y = [1.0, 2.0, 3.0];
        assert_eq!(zero_order_hold(&t, &y, -1.0), 1.0);
        assert_eq!(zero_order_hold(&t, &y, 0.0), 1.0);
        assert_eq!(zero_order_hold(&t, &y, 0.999e-3), 1.0);
        assert_eq!(zero_order_hold(&t, &y, 1e-3), 2.0);
        assert_eq!(zero_order_hold(&t, &y, 1.5e-3), 2.0);
        assert_eq!(zero_order_hold(&t, &y, 10.0), 3.0);
    }
}

/// What the controller receives at a sample: the sensed position and chamber pressures
/// (m, Pa). `control` builds it from the bench's outputs (`Measurement::of`).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Measurement {
    pub y: f64,
    pub p1: f64,
    pub p2: f64,
}

/// The acquisition delay (effect `sensor_delay`): what a sample taken at t reads is the
/// physical signal at t - delay, interpolated linearly between recorded instants. Record
/// the instant [`DelayLine::read_instant_within`] names and the read is exact in time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DelayLine {
    delay: f64,
    /// (time, signals), in time order.
    history: Vec<(f64, Measurement)>,
}

impl DelayLine {
    /// A line holding `m` since `t0` (before its start the signal is held).
    pub fn new(delay: f64, t0: f64, m: Measurement) -> Self {
        DelayLine {
            delay: delay.max(0.0),
            history: vec![(t0, m)],
        }
    }

    pub fn delay(&self) -> f64 {
        self.delay
    }

    /// Record the physical signals at t (t not before the last record).
    pub fn record(&mut self, t: f64, m: Measurement) {
        match self.history.last_mut() {
            Some(last) if last.0 == t => last.1 = m,
            _ => self.history.push((t, m)),
        }
    }

    /// The instant in (from, to) whose signals the sample at `to` will read, if the delay
    /// puts it strictly inside the interval.
    pub fn read_instant_within(&self, from: f64, to: f64) -> Option<f64> {
        let t = to - self.delay;
        (self.delay > 0.0 && t > from && t < to).then_some(t)
    }

    /// The sample taken at t.
    pub fn read(&self, t: f64) -> Measurement {
        let t = t - self.delay;
        let h = &self.history;
        let i = h.partition_point(|(ti, _)| *ti <= t);
        if i == 0 {
            return h[0].1;
        }
        if i == h.len() {
            return h[i - 1].1;
        }
        let ((ta, a), (tb, b)) = (h[i - 1], h[i]);
        let w = (t - ta) / (tb - ta);
        let lerp = |x: f64, y: f64| x + w * (y - x);
        Measurement {
            y: lerp(a.y, b.y),
            p1: lerp(a.p1, b.p1),
            p2: lerp(a.p2, b.p2),
        }
    }

    /// Drop what no read at or after `t` + delay can need (one record before t is kept
    /// for the interpolation).
    pub fn forget_before(&mut self, t: f64) {
        let drop = self.history.partition_point(|(ti, _)| *ti < t - self.delay);
        if drop > 1 {
            self.history.drain(..drop - 1);
        }
    }
}
