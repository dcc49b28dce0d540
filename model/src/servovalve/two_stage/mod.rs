//! Physical model of the MOOG D765 two-stage servovalve (thesis chapter 2): valve
//! electronics closing a loop on the LVDT spool position, torque motor (2.44)-(2.51),
//! flapper/armature with feedback needle and flexure tube (2.35)-(2.39), nozzle-flapper
//! pilot stage (2.1)-(2.7), spool dynamics (2.41)-(2.43) and the land flow model of
//! section 2.2.3 with Table 2.1 (see `lands`).
//!
//! States (7): coil current, armature angle and rate, pilot pressures P_L and P_R, spool
//! position and velocity.
//!
//! Sign conventions: x_s > 0 opens P->A and B->T; the flapper displacement x_f = l_fe
//! theta_f opens the left nozzle (A_fL = pi d_n (x_f0 + x_f), (2.3)); P_L pushes the
//! spool towards +x_s (2.6), (2.42). Positive coil current turns the armature towards
//! +theta_f, which closes the right nozzle and drives the spool towards -x_s, so the
//! amplifier feeds the coils with the inverting polarity.
//!
//! The thesis prints the equations and Table 2.1 but none of the pilot-stage, armature,
//! torque-motor or electronics data. Every such value below is a named constant with the
//! reason for its value; docs/servovalve.md lists them with the checks they meet.
//!
//! Files, one per part of the valve: `spool` (second stage and its lands' flows),
//! `lands` (the rounded-edge land model of Table 2.1), `pilot` (flapper-nozzle pilot
//! stage), `armature` (torque motor, armature, flapper and feedback needle),
//! `electronics` (the valve's spool position loop and coil driver), `design` (every
//! unprinted constant gathered for tuning, and the bench data the valve needs),
//! `dynamics` (the state equations and the `Servovalve` implementation) and `response`
//! (the blocked-port frequency response used for Fig. 2.3).

mod armature;
mod design;
mod dynamics;
mod electronics;
mod jacobian;
pub mod lands;
mod pilot;
mod response;
mod spool;
#[cfg(test)]
mod tests;

pub use armature::{
    AIR_GAP, ARMATURE_DAMPING, ARMATURE_INERTIA, COIL_RESISTANCE, COIL_TURNS, FLAPPER_LENGTH,
    MAGNET_MMF, NEEDLE_LENGTH, NEEDLE_STIFFNESS, POLE_AREA, POLE_ARM, TUBE_LENGTH, TUBE_STIFFNESS,
};
pub use design::{Design, Environment};
pub use electronics::{CURRENT_LIMIT, CURRENT_LOOP_GAIN, DRIVER_VOLTAGE, POSITION_GAIN};
pub use pilot::{
    PilotFlows, DRAIN_DIAMETER, INLET_DIAMETER, NOZZLE_DIAMETER, NOZZLE_GAP, NOZZLE_SEAT_ROUGHNESS,
    PILOT_CD, PILOT_LAMINAR_DP, SEAT_DAMPING, SEAT_STIFFNESS,
};
pub use response::{sine_response, Harmonic};
pub use spool::{
    LandFlows, PILOT_CHAMBER_VOLUME, RATED_STROKE, SLOT_WIDTH, SPOOL_DAMPING_CENTRE,
    SPOOL_DAMPING_SLOPE, SPOOL_DIAMETER, SPOOL_MASS,
};

use crate::params::{Params, ValveParams, BAR, LPM};
use armature::MU_0;
use lands::LandModel;
use std::f64::consts::PI;

/// State indices.
pub const I_COIL: usize = 0;
pub const THETA: usize = 1;
pub const OMEGA: usize = 2;
pub const P_L: usize = 3;
pub const P_R: usize = 4;
pub const X_S: usize = 5;
pub const V_S: usize = 6;
pub const N_STATES: usize = 7;

#[derive(Debug, Clone)]
pub struct TwoStageServovalve {
    d: Design,
    env: Environment,
    lands: LandModel,
    rated_command: f64,
    null_bias: f64,
    // derived constants
    spool_area: f64,
    inlet_k: f64,
    nozzle_k: f64,
    drain_k: f64,
    nozzle_area: f64,
    lfe: f64,
    lre: f64,
    km: f64,
    kmr: f64,
    inductance: f64,
    back_emf: f64,
    resistance: f64,
    /// Current demand per rated stroke that holds the spool there: the feedback needle's
    /// 3 K_r l_re x_rated / K_m, over the current loop's static gain K / (K + R) (A).
    feedforward: f64,
}

impl TwoStageServovalve {
    /// The valve of `vp` in the bench of `p`: `rated_flow` and `rated_pressure_drop`
    /// scale the slot width, `rated_command` and `null_bias` set the command's scale and
    /// offset; the reduced model's other fields do not apply.
    pub fn new(vp: &ValveParams, p: &Params) -> Self {
        Self::with_design(vp, Design::default(), Environment::from_params(p))
    }

    pub fn with_design(vp: &ValveParams, d: Design, env: Environment) -> Self {
        let rated = 19.0 * LPM / (70.0 * BAR).sqrt();
        let scale = vp.rated_flow / vp.rated_pressure_drop.sqrt() / rated;
        let lands = LandModel::new(d.slot_width * scale, env.viscosity, env.density);
        let orifice = |diameter: f64| {
            d.pilot_cd * PI * diameter * diameter / 4.0 * (2.0 / env.density).sqrt()
        };
        // (2.44) reluctance of one air gap at null
        let r0 = d.air_gap / (MU_0 * d.pole_area);
        let ratio = d.pole_arm / d.air_gap;
        // (2.51) torque per ampere
        let km = 4.0 * ratio * (d.magnet_mmf / (2.0 * r0)) * d.coil_turns;
        let lre = d.flapper_length + d.needle_length - 0.5 * d.tube_length;
        TwoStageServovalve {
            spool_area: PI * d.spool_diameter * d.spool_diameter / 4.0,
            inlet_k: orifice(d.inlet_diameter),
            nozzle_k: d.pilot_cd * PI * d.nozzle_diameter * (2.0 / env.density).sqrt(),
            drain_k: orifice(d.drain_diameter),
            nozzle_area: PI * d.nozzle_diameter * d.nozzle_diameter / 4.0,
            // (2.39) equivalent flapper and needle lengths
            lfe: d.flapper_length - 0.5 * d.tube_length,
            lre,
            km,
            // (2.51) magnetic spring
            kmr: 4.0 * ratio * ratio * (d.magnet_mmf / (2.0 * r0)).powi(2) * r0,
            // (2.48) per coil L_c = 2 N_c^2 / R_0 and K_b = N_c lambda_0 a / (R_0 b); two
            // coils in series double both, which makes K_b equal to K_m (power balance)
            inductance: 2.0 * 2.0 * d.coil_turns * d.coil_turns / r0,
            back_emf: 2.0 * d.coil_turns * d.magnet_mmf * ratio / r0,
            resistance: 2.0 * d.coil_resistance,
            feedforward: d.needle_stiffness * lre * d.rated_stroke / km
                * (d.current_loop_gain + 2.0 * d.coil_resistance)
                / d.current_loop_gain,
            d,
            env,
            lands,
            rated_command: vp.rated_command,
            null_bias: vp.null_bias,
        }
    }

    pub fn design(&self) -> &Design {
        &self.d
    }

    pub fn environment(&self) -> &Environment {
        &self.env
    }

    pub fn lands(&self) -> &LandModel {
        &self.lands
    }
}
