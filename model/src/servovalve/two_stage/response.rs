//! Frequency response of the valve alone, ports blocked (Fig. 2.3, Table 1.1).

use super::*;
use crate::servovalve::Servovalve;
use crate::solver::{self, SolverError, SolverStats, Tolerances};
use std::f64::consts::PI;

/// First harmonic of the spool position for a sine command, ports blocked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Harmonic {
    /// |X_s / X_ref|, the amplitude ratio (1 = 0 dB).
    pub gain: f64,
    /// Phase of X_s relative to the command (deg, negative = lag, in (-360, 0]).
    pub phase_deg: f64,
    /// Fraction of the measured time the flapper spends within the last 5 % of its travel
    /// to a nozzle, i.e. seated: the pilot flow is then at its ceiling.
    pub seated_fraction: f64,
    pub stats: SolverStats,
}

/// Drive the valve alone, ports blocked at the environment's supply and tank, with the
/// command `amplitude` * rated * sin(2 pi f t) from rest at null; integrate `settle`
/// cycles, then measure the first harmonic of the spool position over `measure` cycles
/// (Fourier integrals carried as two extra states of the same BDF integration).
pub fn sine_response(
    v: &TwoStageServovalve,
    amplitude: f64,
    freq: f64,
    settle: usize,
    measure: usize,
    rtol: f64,
) -> Result<Harmonic, SolverError> {
    let n = N_STATES;
    let w = 2.0 * PI * freq;
    // states: the valve's, then the two Fourier integrals and the seated time
    let mut x = vec![0.0; n + 3];
    v.initial_state(v.null_bias, &mut x[..n]);
    let mut atol = vec![0.0; n + 3];
    v.absolute_tolerances(&mut atol[..n]);
    let mut scale: Vec<f64> = atol.iter().map(|a| a * 1e4).collect();
    for k in n..n + 3 {
        // 1e-6 of what they reach over one cycle
        atol[k] = 1e-6 * amplitude.max(0.01) / freq;
        scale[k] = 1e-2 / freq;
    }
    let tol = Tolerances {
        rtol,
        atol,
        fixed_step: 0.0,
    };
    let f = |t: f64, x: &[f64], dx: &mut [f64]| {
        let (s, c) = (w * t).sin_cos();
        let u = v.null_bias + amplitude * v.rated_command * s;
        v.derivatives(u, &x[..n], &mut dx[..n]);
        let r = x[X_S] / v.d.rated_stroke;
        dx[n] = r * s;
        dx[n + 1] = r * c;
        // C1 step from 0.90 to 0.95 of the gap: 1 when seated
        let z = ((v.lfe * x[THETA] / v.d.nozzle_gap).abs() - 0.90) / 0.05;
        let z = z.clamp(0.0, 1.0);
        dx[n + 2] = z * z * (3.0 - 2.0 * z);
    };
    // One integration per cycle, as the bench restarts at each communication point (the
    // solver's count of recoverable Newton failures is per integration). The first one
    // is a hundredth of a cycle: at rest the derivatives are all zero, and the solver's
    // first step guess would otherwise jump into the sine and leave the spool a lasting
    // offset (a rate-limited loop barely corrects its mean).
    let mut stats = SolverStats::default();
    let mut bounds = vec![0.0, 0.01 / freq];
    bounds.extend((1..=settle + measure).map(|k| k as f64 / freq));
    for w in bounds.windows(2) {
        if (w[0] - settle as f64 / freq).abs() < 1e-12 / freq {
            x[n..].iter_mut().for_each(|q| *q = 0.0);
        }
        solver::integrate(f, &mut x, w[0], w[1], &tol, &scale, &mut stats)?;
    }
    let span = measure as f64 / freq;
    // x = g sin(wt + phi): int x sin = g T/2 cos(phi), int x cos = g T/2 sin(phi)
    let (a_s, a_c) = (2.0 * x[n] / span, 2.0 * x[n + 1] / span);
    let mut phase = a_c.atan2(a_s).to_degrees();
    if phase > 0.0 {
        phase -= 360.0;
    }
    Ok(Harmonic {
        gain: a_s.hypot(a_c) / amplitude,
        phase_deg: phase,
        seated_fraction: x[n + 2] / span,
        stats,
    })
}
