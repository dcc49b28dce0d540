//! DAO2, the adaptive second-order sliding-mode differentiator of Sidhom (section 5.4).
//!
//! The measured position f(t) = f0(t) + xi(t) (5.59), sampled by the controller board, is
//! differentiated on line to give the velocity and acceleration estimates the control
//! laws need. Reconstructed from the mangled (5.60)-(5.62):
//!
//! ```text
//! (5.61)  s0 = z0 - f,                 s1 = z1 - v0
//! (5.60)  z0' = v0 = -l0 |s0|^(2/3) sign(s0) - Kd0 s0 + z1
//!         z1' = v1 = -l1 |s1|^(1/2) sign(s1) - l2 w - Kd1 s1,   w = int_0^t sign(s1) dt
//! (5.62)  l0' = g0 |s0|^(2/3) sign(s0) s0 = g0 |s0|^(5/3)
//!         l1' = g1 |s1|^(1/2) sign(s1) s1 = g1 |s1|^(3/2)
//!         l2' = g2 s1 w
//! ```
//!
//! Without the linear terms Kd0 s0, Kd1 s1 this is Levant's (2003) second-order
//! differentiator with z2 = -l2 w: Levant's last line z2' = -l2 sign(z2 - v1) is the same
//! thing because z2 - v1 = l1 |s1|^(1/2) sign(s1) + Kd1 s1 has the sign of s1. So the
//! estimates are z0 ~ f, z1 ~ f', z2 = -l2 w ~ f'' (the states, not the corrections v0, v1,
//! which carry the chattering of the sign terms).
//!
//! Not printed in the thesis and chosen here: the adaptation rates g0, g1, g2 (taken as 1
//! in SI units; with errors of micrometres the gains then barely move, so the initial
//! gains carry the behaviour, which is what the thesis means by "depends on the initial
//! values of the algorithm gains") and the initial gains, set by Levant's rule
//! l0 = 2 L^(1/3), l1 = 1.5 L^(1/2), l2 = 1.1 L for a bound L on |f'''|.

/// Gain Kd0 of the thesis (1/s), section 5.6.
pub const KD0: f64 = 200.0;
/// Gain Kd1 of the thesis (1/s), section 5.6.
pub const KD1: f64 = 80.0;

/// Bound on |f'''| (m/s3) the initial gains are designed for: the thesis cycle's 0.2 s
/// moves of 20 mm peak at 131 m/s3 of jerk. A lower bound filters the 16-bit
/// quantisation better but lags on the moves (with 30 m/s3 the velocity error on the
/// thesis move reaches 34 mm/s, 16 % of its peak, against 2 mm/s here); the price is an
/// acceleration noise floor of a few tenths of m/s2 (Levant's L^(2/3) eps^(1/3)).
pub const DESIGN_JERK: f64 = 150.0;

/// Levant's coefficients for the second-order differentiator.
const LEVANT: [f64; 3] = [2.0, 1.5, 1.1];

/// Adaptation rates of (5.62) (SI units), not printed in the thesis.
pub const ADAPTATION_RATES: [f64; 3] = [1.0, 1.0, 1.0];

/// Integration sub-steps per sample. The continuous dynamics (5.60) are integrated by
/// explicit Euler with the measurement held over the sample. The linear part (poles
/// -100 +- 77j 1/s with Kd0 = 200, Kd1 = 80) is stable even with one step per
/// millisecond; what the sub-steps buy is smaller discretisation chattering of the
/// non-Lipschitz terms: Euler with step h leaves |s0| ~ (l0 h)^3, |s1| ~ (l1 h)^2 and a
/// z2 ripple ~ l2 h. With 20 sub-steps at 1 kHz (h = 50 us) the acceleration ripple is
/// l2 h ~ 8 mm/s2 for L = 150 m/s3, well below the resolution the sampling allows.
/// Within the interval the measurement is interpolated linearly between the previous
/// and the new sample (both are known when the update runs): holding the new sample over
/// the interval would feed the differentiator a staircase whose sawtooth (v T, 63 um for
/// 5 mm at 2 Hz) is 14 times the 16-bit quantum and would bias the position estimate by
/// half a sample.
pub const SUBSTEPS: usize = 20;

/// Largest Euler step times the larger linear gain. The linear part of (5.60) has the
/// characteristic polynomial s^2 + Kd0 s + Kd0 Kd1; explicit Euler keeps it stable for
/// h < 2/Kd0 (real roots) and h < 1/Kd1 (complex roots), so h max(Kd0, Kd1) <= 0.5
/// leaves a factor of two on both. The thesis gains need no more than [`SUBSTEPS`]; a
/// Kd0 of 5e4 1/s at 1 kHz, inside the FMU's range, diverged to NaN with 20 (issue 16).
const EULER_GAIN_STEP: f64 = 0.5;

/// Sub-steps per sample: [`SUBSTEPS`], or more when the linear gains need them.
fn stable_substeps(kd0: f64, kd1: f64, period: f64) -> usize {
    let needed = (period * kd0.max(kd1) / EULER_GAIN_STEP).ceil();
    if needed.is_finite() && needed > SUBSTEPS as f64 {
        needed as usize
    } else {
        SUBSTEPS
    }
}

fn sig_pow(x: f64, p: f64) -> f64 {
    x.abs().powf(p) * x.signum()
}

/// Discrete-time DAO2 called once per sample.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Dao2 {
    kd0: f64,
    kd1: f64,
    period: f64,
    substeps: usize,
    /// Initial dynamic gains l0, l1, l2, restored by `reset`.
    gains0: [f64; 3],
    gains: [f64; 3],
    z0: f64,
    z1: f64,
    /// w = int sign(s1) dt of (5.60).
    w: f64,
    /// Previous sample, the start of the interpolated measurement.
    f_prev: f64,
    started: bool,
}

impl Dao2 {
    /// Differentiator with the linear gains Kd0, Kd1 (1/s) sampled every `period` (s),
    /// initial dynamic gains from [`DESIGN_JERK`].
    pub fn new(kd0: f64, kd1: f64, period: f64) -> Self {
        let l = DESIGN_JERK;
        let gains0 = [LEVANT[0] * l.cbrt(), LEVANT[1] * l.sqrt(), LEVANT[2] * l];
        Self::with_gains(kd0, kd1, period, gains0)
    }

    /// Same with explicit initial dynamic gains l0 (m^(1/3)/s), l1 (m^(1/2)/s^(3/2)),
    /// l2 (m/s3).
    pub fn with_gains(kd0: f64, kd1: f64, period: f64, gains0: [f64; 3]) -> Self {
        assert!(
            period > 0.0 && kd0 > 0.0 && kd1 > 0.0,
            "DAO2 gains and period must be > 0"
        );
        Self {
            kd0,
            kd1,
            period,
            substeps: stable_substeps(kd0, kd1, period),
            gains0,
            gains: gains0,
            z0: 0.0,
            z1: 0.0,
            w: 0.0,
            f_prev: 0.0,
            started: false,
        }
    }

    /// The thesis's DAO2: Kd0 = 200 1/s, Kd1 = 80 1/s.
    pub fn thesis(period: f64) -> Self {
        Self::new(KD0, KD1, period)
    }

    /// Restart at rest at position y0 with the initial gains.
    pub fn reset(&mut self, y0: f64) {
        self.z0 = y0;
        self.z1 = 0.0;
        self.w = 0.0;
        self.f_prev = y0;
        self.gains = self.gains0;
        self.started = true;
    }

    /// Current dynamic gains l0, l1, l2.
    pub fn gains(&self) -> [f64; 3] {
        self.gains
    }

    /// Estimates of f, f', f'' after the sample just taken.
    pub fn estimate(&self) -> [f64; 3] {
        [self.z0, self.z1, -self.gains[2] * self.w]
    }

    /// Take a new sample and return the estimates of y, dy/dt, d2y/dt2. The first call
    /// after construction starts at rest on the sample.
    pub fn update(&mut self, y_measured: f64) -> [f64; 3] {
        if !self.started {
            self.reset(y_measured);
            return self.estimate();
        }
        let n = self.substeps as f64;
        let h = self.period / n;
        let [g0, g1, g2] = ADAPTATION_RATES;
        for i in 0..self.substeps {
            // first-order hold between the last two samples, see [`SUBSTEPS`]
            let f = self.f_prev + (y_measured - self.f_prev) * (i + 1) as f64 / n;
            let [l0, l1, l2] = self.gains;
            // (5.61) sliding surfaces
            let s0 = self.z0 - f;
            let p0 = sig_pow(s0, 2.0 / 3.0);
            // (5.60) first layer
            let v0 = -l0 * p0 - self.kd0 * s0 + self.z1;
            let s1 = self.z1 - v0;
            let p1 = sig_pow(s1, 0.5);
            // (5.60) second layer, the integral term playing Levant's z2
            let v1 = -l1 * p1 - l2 * self.w - self.kd1 * s1;
            self.z0 += h * v0;
            self.z1 += h * v1;
            self.w += h * s1.signum();
            // (5.62) adaptive gains; l2 is kept at or above its initial value (projection)
            // because its law can decrease it and a gain under the jerk bound loses the
            // exactness of the second derivative
            self.gains[0] = l0 + h * g0 * p0 * s0;
            self.gains[1] = l1 + h * g1 * p1 * s1;
            self.gains[2] = (l2 + h * g2 * s1 * self.w).max(self.gains0[2]);
        }
        self.f_prev = y_measured;
        self.estimate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    const PERIOD: f64 = 1e-3;
    const AMPLITUDE: f64 = 5e-3;
    const FREQ: f64 = 2.0;
    /// 16-bit converter over the 300 mm stroke.
    const LSB: f64 = 0.3 / 65536.0;

    fn quantise(y: f64) -> f64 {
        (y / LSB).round() * LSB
    }

    /// Levant's initial gains for a jerk bound l (m/s3).
    fn levant(l: f64) -> [f64; 3] {
        [LEVANT[0] * l.cbrt(), LEVANT[1] * l.sqrt(), LEVANT[2] * l]
    }

    /// Max position, velocity and acceleration errors over [t_from, t_to] for a sampled
    /// quantised sine that the differentiator starts on with the given initial estimate.
    fn sine_errors(mut d: Dao2, y0: f64, t_from: f64, t_to: f64) -> (f64, f64, f64) {
        let w = 2.0 * PI * FREQ;
        d.reset(y0);
        let (mut ep, mut ev, mut ea) = (0.0f64, 0.0f64, 0.0f64);
        let n = (t_to / PERIOD).round() as usize;
        for k in 1..=n {
            let t = k as f64 * PERIOD;
            let y = AMPLITUDE * (w * t).sin();
            let [p, v, a] = d.update(quantise(y));
            if t >= t_from {
                ep = ep.max((p - y).abs());
                ev = ev.max((v - AMPLITUDE * w * (w * t).cos()).abs());
                ea = ea.max((a + AMPLITUDE * w * w * (w * t).sin()).abs());
            }
        }
        (ep, ev, ea)
    }

    #[test]
    fn recovers_velocity_and_acceleration_of_a_quantised_sine() {
        let w = 2.0 * PI * FREQ;
        let (vamp, aamp) = (AMPLITUDE * w, AMPLITUDE * w * w);
        let (ep, ev, ea) = sine_errors(Dao2::thesis(PERIOD), 0.0, 1.0, 3.0);
        eprintln!(
            "DAO2 sine 5 mm 2 Hz, 16-bit, L = {DESIGN_JERK}: |e_y| {:.2} um, |e_v| {:.2} mm/s ({:.2} %), |e_a| {:.3} m/s2 ({:.1} %)",
            ep * 1e6,
            ev * 1e3,
            100.0 * ev / vamp,
            ea,
            100.0 * ea / aamp
        );
        assert!(ep < 2.0 * LSB, "position error {ep}");
        assert!(ev < 0.03 * vamp, "velocity error {ev} vs amplitude {vamp}");
        // The acceleration is quantisation-limited: Levant's accuracy bound scales as
        // L^(2/3) eps^(1/3), ~0.4 m/s2 for L = 150 m/s3 and eps = LSB/2, which is most of
        // this slow sine's 0.79 m/s2. Gains designed for the sine's own jerk (10 m/s3)
        // bring it to a fraction of the amplitude.
        assert!(ea < 0.7, "acceleration error {ea}");
        let slow = Dao2::with_gains(KD0, KD1, PERIOD, levant(10.0));
        let (_, ev10, ea10) = sine_errors(slow, 0.0, 1.0, 3.0);
        eprintln!(
            "DAO2 sine, L = 10: |e_v| {:.2} mm/s ({:.2} %), |e_a| {:.3} m/s2 ({:.1} %)",
            ev10 * 1e3,
            100.0 * ev10 / vamp,
            ea10,
            100.0 * ea10 / aamp
        );
        assert!(ev10 < 0.03 * vamp, "velocity error {ev10}");
        assert!(
            ea10 < 0.3 * aamp,
            "acceleration error {ea10} vs amplitude {aamp}"
        );
    }

    #[test]
    fn follows_the_thesis_move() {
        // the 7th-order move it was designed for, 16-bit position, started at rest
        let tr = super::super::trajectory::Trajectory::thesis();
        let mut d = Dao2::thesis(PERIOD);
        d.reset(tr.at(0.0)[0]);
        let (mut ev, mut ea, mut amax) = (0.0f64, 0.0f64, 0.0f64);
        for k in 1..3000 {
            let t = k as f64 * PERIOD;
            let [y, v, a, _] = tr.at(t);
            let [_, ve, ae] = d.update(quantise(y));
            ev = ev.max((ve - v).abs());
            ea = ea.max((ae - a).abs());
            amax = amax.max(a.abs());
        }
        let vmax = tr.peak_speed();
        eprintln!(
            "DAO2 thesis move, 16-bit: |e_v| {:.2} mm/s ({:.2} % of peak), |e_a| {:.3} m/s2 ({:.1} % of peak)",
            ev * 1e3,
            100.0 * ev / vmax,
            ea,
            100.0 * ea / amax
        );
        assert!(ev < 0.02 * vmax, "velocity error {ev}");
        assert!(ea < 0.25 * amax, "acceleration error {ea}");
    }

    #[test]
    fn converges_from_a_wrong_initial_condition() {
        let w = 2.0 * PI * FREQ;
        let vamp = AMPLITUDE * w;
        // start 10 mm off with the piston moving at full speed
        let (_, ev_early, _) = sine_errors(Dao2::thesis(PERIOD), 10e-3, 0.0, 0.01);
        let (ep, ev, _) = sine_errors(Dao2::thesis(PERIOD), 10e-3, 0.5, 2.0);
        eprintln!(
            "DAO2 from 10 mm off: early |e_v| {:.1} mm/s, after 0.5 s |e_y| {:.2} um |e_v| {:.2} mm/s",
            ev_early * 1e3,
            ep * 1e6,
            ev * 1e3
        );
        assert!(
            ev_early > vamp,
            "the test should start far from the solution"
        );
        assert!(ep < 2.0 * LSB, "position error {ep}");
        assert!(ev < 0.03 * vamp, "velocity error {ev}");
    }

    #[test]
    fn exact_on_a_ramp_and_reset_restores() {
        // constant velocity: the estimate must settle on it with no lag error
        let mut d = Dao2::thesis(PERIOD);
        let speed = 0.2;
        let mut est = [0.0; 3];
        for k in 0..1000 {
            est = d.update(speed * k as f64 * PERIOD);
        }
        assert!(
            (est[1] - speed).abs() < 1e-3 * speed,
            "ramp velocity {}",
            est[1]
        );
        assert!(est[2].abs() < 0.05, "ramp acceleration {}", est[2]);
        d.reset(0.004);
        assert_eq!(d.estimate(), [0.004, 0.0, 0.0]);
        assert_eq!(d.gains(), Dao2::thesis(PERIOD).gains);
    }
}
