//! Torque motor (2.44)-(2.51) and the armature it turns, with the flapper and the
//! feedback needle on the flexure tube (2.35)-(2.39).

use super::TwoStageServovalve;
use std::f64::consts::PI;

// ---------------------------------------------------------------------------------
// Flapper, armature, feedback needle
// ---------------------------------------------------------------------------------

/// Rotary inertia J_f of armature, flapper and needle about the flexure pivot (kg.m2):
/// a 2 g, 22 mm armature with its flapper and needle. With the tube, needle and magnetic
/// springs it puts the armature mode near 1.5 kHz, above the valve's bandwidth.
pub const ARMATURE_INERTIA: f64 = 1.0e-7;

/// Viscous damping B_f of the armature rotation (N.m.s/rad), (2.39): squeeze film of the
/// flapper between its nozzles in the oil of the flapper chamber; 0.6 of critical on the
/// armature's own springs, so the armature mode does not ring in the spool loop.
pub const ARMATURE_DAMPING: f64 = 1.2e-3;

/// Rotational stiffness l_t^2 K_t of the flexure tube (N.m/rad), (2.39). Chosen well
/// above the torque motor's magnetic spring K_mr (3.3 N.m/rad) so the armature is stable:
/// net 9.4 N.m/rad with the needle, i.e. 0.047 N.m to seat the flapper on a nozzle.
pub const TUBE_STIFFNESS: f64 = 12.0;

/// Flexure tube length l_t (m); enters l_fe and l_re (2.39).
pub const TUBE_LENGTH: f64 = 8e-3;

/// Distance l_f from the tube end to the nozzle axis (m), (2.38); l_fe = l_f - l_t/2.
pub const FLAPPER_LENGTH: f64 = 12e-3;

/// Needle length l_r from the nozzles to the ball in the spool (m); l_re = l_f + l_r - l_t/2.
pub const NEEDLE_LENGTH: f64 = 10e-3;

/// Feedback needle tip stiffness 3 K_r (N/m), (2.39), (2.42): a 0.5 mm steel wire
/// cantilevered over l_r, 3 E I / l_r^3.
pub const NEEDLE_STIFFNESS: f64 = 2000.0;

// ---------------------------------------------------------------------------------
// Torque motor (2.44)-(2.51)
// ---------------------------------------------------------------------------------

/// Magnetomotive force lambda_0 of the permanent magnet (A.turns), (2.44): 0.4 T in the
/// air gaps at null.
pub const MAGNET_MMF: f64 = 160.0;

/// Turns N_c of each of the two coils, (2.44).
pub const COIL_TURNS: f64 = 400.0;

/// Air gap b at null (m), (2.44).
pub const AIR_GAP: f64 = 0.25e-3;

/// Pole face area A of each air gap (m2); R_0 = b / (mu_0 A), (2.44).
pub const POLE_AREA: f64 = 16e-6;

/// Distance a from the pivot to the pole faces (m), (2.46)-(2.51).
pub const POLE_ARM: f64 = 10e-3;

/// Resistance R of each coil (ohm), (2.47); the two coils are in series.
pub const COIL_RESISTANCE: f64 = 20.0;

/// Vacuum permeability (H/m).
pub(super) const MU_0: f64 = 4e-7 * PI;

impl TwoStageServovalve {
    /// (K_m, K_mr, L, K_b, R) of the torque motor and coils, (2.48), (2.51).
    pub fn torque_motor(&self) -> [f64; 5] {
        [
            self.km,
            self.kmr,
            self.inductance,
            self.back_emf,
            self.resistance,
        ]
    }
}
