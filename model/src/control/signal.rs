//! The position references of the thesis's experiments as functions of time, with their
//! first three derivatives (the backstepping laws need them up to the jerk).

use std::f64::consts::PI;

use super::trajectory::Trajectory;

/// The position reference a scenario follows.
#[derive(Debug, Clone, PartialEq)]
pub enum Signal {
    /// 7th-order polynomial moves (section 5.5).
    Moves(Trajectory),
    /// Steps between two positions at the given times (section 4.4, Fig. 4.8).
    Steps {
        low: f64,
        high: f64,
        times: Vec<f64>,
    },
    /// y_d = amplitude sin(2 pi f t), with its analytic derivatives (Figs. 4.9-4.14).
    Sine { amplitude: f64, frequency: f64 },
    /// A logarithmic sweep, y_d = amplitude sin(phi(t)) with the frequency rising
    /// geometrically from `f_start` to `f_end` over `duration` (s) and holding `f_end`
    /// after: the frequency responses of Figs. 4.9-4.14 in one run instead of one sine
    /// per frequency.
    Sweep {
        amplitude: f64,
        f_start: f64,
        f_end: f64,
        duration: f64,
    },
    /// A constant-velocity ramp from `from` to `to` (m) starting at `start` and lasting
    /// `duration` (s), holding its ends: the velocity-tracking test of a position loop.
    Ramp {
        start: f64,
        from: f64,
        to: f64,
        duration: f64,
    },
}

impl Signal {
    /// y_d and its first three derivatives at t.
    pub fn at(&self, t: f64) -> [f64; 4] {
        match self {
            Signal::Moves(tr) => tr.at(t),
            Signal::Steps { low, high, times } => {
                let n = times.iter().filter(|&&ts| t >= ts).count();
                [if n % 2 == 1 { *high } else { *low }, 0.0, 0.0, 0.0]
            }
            Signal::Sine {
                amplitude: a,
                frequency,
            } => {
                let w = 2.0 * PI * frequency;
                let (s, c) = (w * t).sin_cos();
                [a * s, a * w * c, -a * w * w * s, -a * w * w * w * c]
            }
            Signal::Sweep {
                amplitude: a,
                f_start,
                f_end,
                duration,
            } => {
                // phi' = w = 2 pi f0 k^(t/T), k = f1/f0, so w' = r w and w'' = r^2 w with
                // r = ln(k)/T while sweeping; after it, a sine at f1 (r = 0)
                let r = (f_end / f_start).ln() / duration;
                let w0 = 2.0 * PI * f_start;
                let swept = |t: f64| {
                    if r == 0.0 {
                        w0 * t
                    } else {
                        w0 * ((r * t).exp() - 1.0) / r
                    }
                };
                let (phi, w, r) = if t < *duration {
                    (swept(t), w0 * (r * t).exp(), r)
                } else {
                    let w1 = 2.0 * PI * f_end;
                    (swept(*duration) + w1 * (t - duration), w1, 0.0)
                };
                let (dw, d2w) = (r * w, r * r * w);
                let (s, c) = phi.sin_cos();
                [
                    a * s,
                    a * c * w,
                    a * (c * dw - s * w * w),
                    a * (c * d2w - 3.0 * s * w * dw - c * w * w * w),
                ]
            }
            Signal::Ramp {
                start,
                from,
                to,
                duration,
            } => {
                let tau = (t - start) / duration;
                if tau <= 0.0 {
                    [*from, 0.0, 0.0, 0.0]
                } else if tau >= 1.0 {
                    [*to, 0.0, 0.0, 0.0]
                } else {
                    [from + (to - from) * tau, (to - from) / duration, 0.0, 0.0]
                }
            }
        }
    }
}
