//! Valve electronics: the proportional loop on the LVDT spool position with the needle's
//! feedforward, and the current-limited, voltage-limited coil driver.

use super::TwoStageServovalve;

// ---------------------------------------------------------------------------------
// Valve electronics
// ---------------------------------------------------------------------------------

/// Output rail of the coil driver (V): the D765's electronics run from a +-15 V supply.
/// At large, fast commands the coils' inductance (51 mH) cannot reverse the current
/// faster than this allows, which adds phase lag there (docs/servovalve.md).
pub const DRIVER_VOLTAGE: f64 = 15.0;

/// Gain of the coil driver's current loop (V/A): (K + R)/L puts the loop near 2.9 kHz
/// on the coils' series inductance, so the coils' L/R lag (1.3 ms) is hidden as in any
/// servovalve current driver.
pub const CURRENT_LOOP_GAIN: f64 = 900.0;

/// Current limit of the driver (A): above the 0.15 A that seats the flapper on a nozzle
/// from any spool position, so large errors are limited by the pilot stage's flow, not
/// by the current.
pub const CURRENT_LIMIT: f64 = 0.25;

/// Proportional gain of the spool position controller (A per rated stroke of error),
/// 14 times the 36 mA the feedback needle needs at full stroke. About the largest gain
/// that leaves the spool loop well damped (closed-loop poles at 750 Hz, 0.56 of
/// critical): small-signal -3 dB near 840 Hz, the D765's "1 kHz at 5 %" class. The
/// electronics add the calibrated feedforward of the needle's current (no integrator:
/// it winds up while the pilot stage saturates, 37 % overshoot on a full step).
pub const POSITION_GAIN: f64 = 0.5;

impl TwoStageServovalve {
    /// Spool position demanded by the command, as a fraction of the rated stroke.
    pub(super) fn reference(&self, command: f64) -> f64 {
        ((command - self.null_bias) / self.rated_command).clamp(-1.0, 1.0)
    }
}

/// Smooth saturation of an amplifier stage at +-`limit`: linear to within 1e-4 up to a
/// tenth of the limit and to 3 % at half of it, unlike tanh, which already compresses by
/// 0.3 % at a tenth.
pub(super) fn saturate(x: f64, limit: f64) -> f64 {
    x / (1.0 + (x / limit).powi(4)).powf(0.25)
}

/// Inverse of [`saturate`] for |y| < limit.
pub(super) fn unsaturate(y: f64, limit: f64) -> f64 {
    let r = (y / limit).clamp(-0.999_999, 0.999_999);
    y / (1.0 - r.powi(4)).powf(0.25)
}
