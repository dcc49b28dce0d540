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

pub mod lands;

use super::{signed_sqrt, PortFlows, PortPressures, Servovalve};
use crate::params::{Params, ValveParams, BAR, LPM};
use crate::solver::{self, SolverError, SolverStats, Tolerances};
use lands::{LandModel, LAND_OVERLAPS};
use std::f64::consts::PI;

// ---------------------------------------------------------------------------------
// Second stage
// ---------------------------------------------------------------------------------

/// Spool travel at rated command, 10 V of LVDT signal (m). The thesis plots spool
/// position in LVDT volts and never prints the scale. With the Table 2.1 land model the
/// blocked-port pressure gain is a fixed number of bar per micrometre, so this scale is
/// what turns it into bar/V: 0.417 mm gives the 827 bar/V of the thesis model (Fig.
/// 2.10(b)); it lies in the usual +-0.4..0.5 mm range of D765-size spools.
pub const RATED_STROKE: f64 = 0.417e-3;

/// Total slot width n*w_s of one metering land (m), sized so that two lands in series
/// pass the rated 19 L/min at 70 bar and 10 V (Table 1.1): about 80 % of the
/// circumference of the 5.6 mm spool.
pub const SLOT_WIDTH: f64 = 14.2e-3;

/// Diameter d_s of the spool ends that the pilot pressures act on (m), (2.42). With the
/// pilot flow of the nozzles below it sets the spool's maximum speed, which is what
/// makes the large-signal bandwidth smaller (Fig. 2.3): 5.6 mm gives about 0.22 m/s.
pub const SPOOL_DIAMETER: f64 = 5.6e-3;

/// Spool mass m_s (kg), (2.42): a 5.6 mm steel spool about 40 mm long with the LVDT core.
pub const SPOOL_MASS: f64 = 0.012;

/// a_s of (2.41), viscous friction of the spool in its sleeve at centre (N.s/m):
/// mu pi d_s L / e_s for about 8 mm of sealing land length in the 2.4 um clearance.
pub const SPOOL_DAMPING_CENTRE: f64 = 2.3;

/// b_s of (2.41), growth of the spool friction with stroke (N.s/m per m): mu pi d_s / e_s,
/// one land length of wetted contact more per unit of travel.
pub const SPOOL_DAMPING_SLOPE: f64 = 290.0;

/// Oil volume of each pilot chamber at spool centre, V_L0 = V_R0 of (2.6)-(2.7) (m3):
/// the end cap of the spool and the drilling to the nozzle.
pub const PILOT_CHAMBER_VOLUME: f64 = 0.15e-6;

// ---------------------------------------------------------------------------------
// Pilot stage
// ---------------------------------------------------------------------------------

/// Discharge coefficient of every pilot orifice, C_d0 = C_df = C_dd = C_f (2.8).
pub const PILOT_CD: f64 = 0.61;

/// Diameter d_0 of the two upstream fixed orifices (m), (2.1)-(2.2). It is the pilot
/// stage's flow ceiling: with a nozzle closed the chamber flow cannot exceed what this
/// orifice passes, which saturates the spool speed at large, fast commands.
pub const INLET_DIAMETER: f64 = 0.27e-3;

/// Nozzle diameter d_n (m), (2.3)-(2.4), typical of MOOG pilot stages.
pub const NOZZLE_DIAMETER: f64 = 0.45e-3;

/// Flapper-nozzle gap at null x_f0 (m), (2.3)-(2.4). With d_0 and d_n it gives
/// alpha_f = 4 d_n x_f0 / d_0^2 = 0.99, the linear and symmetric bridge of Fig. 2.7.
pub const NOZZLE_GAP: f64 = 40e-6;

/// Diameter d_d of the drain orifice of the flapper chamber (m), (2.5): keeps P_E a
/// few bar above tank with the nozzles' 0.65 L/min.
pub const DRAIN_DIAMETER: f64 = 0.8e-3;

/// Pressure drop below which the pilot orifices turn laminar (Pa), for `signed_sqrt`:
/// changes the flow by less than 1e-6 at the 100 bar the orifices work at.
pub const PILOT_LAMINAR_DP: f64 = 0.1 * BAR;

/// Smoothing length of the nozzle gap as the flapper seats on a nozzle (m): the
/// residual gap of the seat's surface roughness, 0.1 um at contact.
pub const NOZZLE_SEAT_ROUGHNESS: f64 = 0.2e-6;

/// Hertz stiffness of the flapper on a nozzle rim (N/m^1.5), F = K p^1.5 for a
/// penetration p: about 2 um (5 % of the gap) under the largest torque-motor force. The
/// nozzles are the flapper's travel stops; a stiffer seat only shortens the solver's steps.
pub const SEAT_STIFFNESS: f64 = 5e9;

/// Hunt-Crossley damping of the seat contact (s/m), F = K p^1.5 (1 + c dp/dt): dissipates
/// the impact of the flapper on the rim without a discontinuity at first contact.
pub const SEAT_DAMPING: f64 = 5.0;

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

/// Vacuum permeability (H/m).
const MU_0: f64 = 4e-7 * PI;

/// Every unprinted constant of the model, gathered so that tuning tools can vary them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Design {
    pub rated_stroke: f64,
    pub slot_width: f64,
    pub spool_diameter: f64,
    pub spool_mass: f64,
    pub spool_damping_centre: f64,
    pub spool_damping_slope: f64,
    pub pilot_chamber_volume: f64,
    pub pilot_cd: f64,
    pub inlet_diameter: f64,
    pub nozzle_diameter: f64,
    pub nozzle_gap: f64,
    pub drain_diameter: f64,
    pub armature_inertia: f64,
    pub armature_damping: f64,
    pub tube_stiffness: f64,
    pub tube_length: f64,
    pub flapper_length: f64,
    pub needle_length: f64,
    pub needle_stiffness: f64,
    pub magnet_mmf: f64,
    pub coil_turns: f64,
    pub air_gap: f64,
    pub pole_area: f64,
    pub pole_arm: f64,
    pub coil_resistance: f64,
    pub driver_voltage: f64,
    pub current_loop_gain: f64,
    pub current_limit: f64,
    pub position_gain: f64,
}

impl Default for Design {
    fn default() -> Self {
        Design {
            rated_stroke: RATED_STROKE,
            slot_width: SLOT_WIDTH,
            spool_diameter: SPOOL_DIAMETER,
            spool_mass: SPOOL_MASS,
            spool_damping_centre: SPOOL_DAMPING_CENTRE,
            spool_damping_slope: SPOOL_DAMPING_SLOPE,
            pilot_chamber_volume: PILOT_CHAMBER_VOLUME,
            pilot_cd: PILOT_CD,
            inlet_diameter: INLET_DIAMETER,
            nozzle_diameter: NOZZLE_DIAMETER,
            nozzle_gap: NOZZLE_GAP,
            drain_diameter: DRAIN_DIAMETER,
            armature_inertia: ARMATURE_INERTIA,
            armature_damping: ARMATURE_DAMPING,
            tube_stiffness: TUBE_STIFFNESS,
            tube_length: TUBE_LENGTH,
            flapper_length: FLAPPER_LENGTH,
            needle_length: NEEDLE_LENGTH,
            needle_stiffness: NEEDLE_STIFFNESS,
            magnet_mmf: MAGNET_MMF,
            coil_turns: COIL_TURNS,
            air_gap: AIR_GAP,
            pole_area: POLE_AREA,
            pole_arm: POLE_ARM,
            coil_resistance: COIL_RESISTANCE,
            driver_voltage: DRIVER_VOLTAGE,
            current_loop_gain: CURRENT_LOOP_GAIN,
            current_limit: CURRENT_LIMIT,
            position_gain: POSITION_GAIN,
        }
    }
}

/// Fluid and circuit data the valve needs from the bench.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Environment {
    pub density: f64,
    pub viscosity: f64,
    pub bulk_modulus: f64,
    /// Supply and tank pressure used when the ports are not given (`derivatives`).
    pub supply: f64,
    pub tank: f64,
}

impl Environment {
    /// The oil of a parameter set at its temperature, and its supply and tank.
    pub fn from_params(p: &Params) -> Self {
        let fluid = crate::actuator::fluid_in_use(p);
        Environment {
            density: fluid.density,
            viscosity: fluid
                .dynamic_viscosity(fluid.temperature, crate::fluid::ATMOSPHERIC_PRESSURE),
            bulk_modulus: fluid.bulk_modulus,
            supply: p.supply_pressure,
            tank: p.tank_pressure,
        }
    }

    /// The section 2.2.3 experiments: supply 215 bar, tank 2 bar, oil at 40 degC.
    pub fn thesis_test() -> Self {
        Environment::from_params(&Params {
            supply_pressure: 215.0 * BAR,
            tank_pressure: 2.0 * BAR,
            ..Params::default()
        })
    }
}

/// State indices.
pub const I_COIL: usize = 0;
pub const THETA: usize = 1;
pub const OMEGA: usize = 2;
pub const P_L: usize = 3;
pub const P_R: usize = 4;
pub const X_S: usize = 5;
pub const V_S: usize = 6;
pub const N_STATES: usize = 7;

/// Flows of the pilot bridge (m3/s) and the flapper chamber pressure P_E (Pa).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PilotFlows {
    pub q_pl: f64,
    pub q_pr: f64,
    pub q_le: f64,
    pub q_re: f64,
    pub p_e: f64,
}

/// The four land flows Q_s1..Q_s4 of (2.40) (m3/s) and their openings x_si (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LandFlows {
    pub q: [f64; 4],
    pub x: [f64; 4],
}

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

    /// Spool position demanded by the command, as a fraction of the rated stroke.
    fn reference(&self, command: f64) -> f64 {
        ((command - self.null_bias) / self.rated_command).clamp(-1.0, 1.0)
    }

    /// Land flows Q_s1..Q_s4 (2.18), (2.40).
    pub fn land_flows(&self, xs: f64, p: &PortPressures) -> LandFlows {
        let [x10, x20, x30, x40] = LAND_OVERLAPS;
        // (2.18) local openings: lands 1, 3 open with +x_s, lands 2, 4 with -x_s
        let x = [xs - x10, -xs - x20, xs - x30, -xs - x40];
        let l = &self.lands;
        LandFlows {
            q: [
                l.flow(x[0], p.supply - p.a),
                l.flow(x[1], p.a - p.tank),
                l.flow(x[2], p.b - p.tank),
                l.flow(x[3], p.supply - p.b),
            ],
            x,
        }
    }

    /// (2.43) axial flow force on the spool (N), positive towards +x_s.
    pub fn spool_flow_force(&self, f: &LandFlows) -> f64 {
        let l = &self.lands;
        let force = |k: usize| l.flow_force(f.x[k], f.q[k]);
        force(1) - force(0) + force(3) - force(2)
    }

    /// Nozzle gaps x_f0 +- x_f, kept positive through the seat roughness when the flapper
    /// seats on a nozzle.
    fn gaps(&self, xf: f64) -> (f64, f64) {
        let e = NOZZLE_SEAT_ROUGHNESS;
        let soft = |g: f64| 0.5 * (g + (g * g + e * e).sqrt());
        (soft(self.d.nozzle_gap + xf), soft(self.d.nozzle_gap - xf))
    }

    /// (2.1)-(2.5): the pilot flows at chamber pressures P_L, P_R and flapper position
    /// x_f, with P_E from the flow balance of the flapper chamber Q_LE + Q_RE = Q_ET (2.5),
    /// solved by safeguarded Newton (the chamber is small, its compressibility negligible).
    pub fn pilot_flows(&self, ps: f64, pt: f64, pl: f64, pr: f64, xf: f64) -> PilotFlows {
        let t = PILOT_LAMINAR_DP;
        let ss = |p: f64| signed_sqrt(p, t);
        let dss = |p: f64| (0.5 * p * p + t * t) / (p * p + t * t).powf(1.25);
        let (gl, gr) = self.gaps(xf);
        let (kl, kr, kd) = (self.nozzle_k * gl, self.nozzle_k * gr, self.drain_k);
        let balance = |pe: f64| {
            let f = kl * ss(pl - pe) + kr * ss(pr - pe) - kd * ss(pe - pt);
            let df = -kl * dss(pl - pe) - kr * dss(pr - pe) - kd * dss(pe - pt);
            (f, df)
        };
        let mut lo = pt.min(pl).min(pr);
        let mut hi = pt.max(pl).max(pr);
        // first guess: nozzle flows at P_E = P_T through the drain orifice
        let q0 = kl * ss(pl - pt) + kr * ss(pr - pt);
        let mut pe = (pt + (q0 / kd).powi(2) * q0.signum()).clamp(lo, hi);
        for _ in 0..100 {
            let (f, df) = balance(pe);
            if f > 0.0 {
                lo = pe;
            } else {
                hi = pe;
            }
            let mut next = pe - f / df;
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            let done = (next - pe).abs() <= 1e-13 * (pe.abs() + BAR) || hi - lo < 1e-9;
            pe = next;
            if done {
                break;
            }
        }
        PilotFlows {
            q_pl: self.inlet_k * ss(ps - pl), // (2.1)
            q_pr: self.inlet_k * ss(ps - pr), // (2.2)
            q_le: kl * ss(pl - pe),           // (2.3)
            q_re: kr * ss(pr - pe),           // (2.4)
            p_e: pe,                          // (2.5)
        }
    }

    /// Right-hand side with the spool flow force `f_flow` (N) already known.
    fn rhs(&self, command: f64, x: &[f64], ps: f64, pt: f64, f_flow: f64, dx: &mut [f64]) {
        let d = &self.d;
        let (i, th, om) = (x[I_COIL], x[THETA], x[OMEGA]);
        let (pl, pr, xs, vs) = (x[P_L], x[P_R], x[X_S], x[V_S]);

        // Electronics: proportional control of the LVDT spool position plus the calibrated
        // feedforward of the current the feedback needle needs, current-limited, then a
        // voltage-limited current loop on the coils (inverting polarity, see above).
        let s_ref = self.reference(command);
        let e = s_ref - xs / d.rated_stroke;
        let lim = d.current_limit;
        let i_ref = -saturate(d.position_gain * e + self.feedforward * s_ref, lim);
        let u = saturate(d.current_loop_gain * (i_ref - i), d.driver_voltage);
        // (2.48) coil electrics: resistance, inductance and back-EMF of the armature
        dx[I_COIL] = (u - self.resistance * i - self.back_emf * om) / self.inductance;

        // Pilot stage (2.1)-(2.5) and chamber compressibility (2.6)-(2.7)
        let xf = self.lfe * th;
        let pf = self.pilot_flows(ps, pt, pl, pr, xf);
        let a = self.spool_area;
        let v0 = d.pilot_chamber_volume;
        let beta = self.env.bulk_modulus;
        dx[P_L] = beta / (v0 + a * xs) * (pf.q_pl - pf.q_le - a * vs); // (2.6)
        dx[P_R] = beta / (v0 - a * xs) * (pf.q_pr - pf.q_re + a * vs); // (2.7)

        // Armature (2.39)
        // needle deflection at its tip x_r = x_s - l_re theta_f
        let xr = xs - self.lre * th;
        // hydrostatic force (P_L - P_R) pi d_n^2 / 4 and jet force
        // 4 rho / (pi d_n^2) (Q_LE^2 - Q_RE^2) on the flapper
        let f_hs = (pl - pr) * self.nozzle_area;
        let f_hd = self.env.density / self.nozzle_area * (pf.q_le * pf.q_le - pf.q_re * pf.q_re);
        let f_seat = self.seat_force(xf, self.lfe * om);
        let t_m = self.kmr * th + self.km * i; // (2.51)
        dx[THETA] = om;
        dx[OMEGA] = (t_m + d.needle_stiffness * xr * self.lre - d.tube_stiffness * th
            + (f_hs + f_hd + f_seat) * self.lfe
            - d.armature_damping * om)
            / d.armature_inertia;

        // Spool (2.41)-(2.42)
        let bs = d.spool_damping_centre + d.spool_damping_slope * xs.abs(); // (2.41)
        dx[X_S] = vs;
        dx[V_S] = (a * (pl - pr) - d.needle_stiffness * xr - bs * vs + f_flow) / d.spool_mass;
    }

    /// Contact force of the nozzles on the flapper (N), positive towards +x_f: Hertz with
    /// Hunt-Crossley damping, zero while the flapper is clear of both nozzles.
    fn seat_force(&self, xf: f64, vf: f64) -> f64 {
        let left = (-(self.d.nozzle_gap + xf)).max(0.0); // penetration into the left nozzle
        let right = (-(self.d.nozzle_gap - xf)).max(0.0);
        SEAT_STIFFNESS
            * (left.powf(1.5) * (1.0 - SEAT_DAMPING * vf)
                - right.powf(1.5) * (1.0 + SEAT_DAMPING * vf))
    }

    /// Static pilot bridge (no chamber flow) at flapper position x_f: (P_L, P_R, P_E).
    fn static_bridge(&self, ps: f64, pt: f64, xf: f64) -> (f64, f64, f64) {
        let t = PILOT_LAMINAR_DP;
        let ss = |p: f64| signed_sqrt(p, t);
        let (gl, gr) = self.gaps(xf);
        let dss = |p: f64| (0.5 * p * p + t * t) / (p * p + t * t).powf(1.25);
        let chamber = |g: f64, pe: f64| {
            // Q_P(P_S - P) = Q_nozzle(P - P_E): the turbulent closed form, then Newton on
            // the laminar-cored laws the right-hand side uses
            let (a, b) = (self.inlet_k, self.nozzle_k * g);
            let mut p = (ps * a * a + pe * b * b) / (a * a + b * b);
            for _ in 0..8 {
                let f = a * ss(ps - p) - b * ss(p - pe);
                let df = -a * dss(ps - p) - b * dss(p - pe);
                p = (p - f / df).clamp(pe.min(ps), ps.max(pe));
            }
            p
        };
        let (mut lo, mut hi) = (pt, ps);
        for _ in 0..80 {
            let pe = 0.5 * (lo + hi);
            let (pl, pr) = (chamber(gl, pe), chamber(gr, pe));
            let q = self.nozzle_k * (gl * ss(pl - pe) + gr * ss(pr - pe));
            if q > self.drain_k * ss(pe - pt) {
                lo = pe;
            } else {
                hi = pe;
            }
        }
        let pe = 0.5 * (lo + hi);
        (chamber(gl, pe), chamber(gr, pe), pe)
    }

    /// Rest state for a constant command with supply `ps` and tank `pt`.
    pub fn rest_state(&self, command: f64, ps: f64, pt: f64, x: &mut [f64]) {
        let d = &self.d;
        let a = self.spool_area;
        let s_ref = self.reference(command);
        let mut xs = s_ref * d.rated_stroke;
        // The spool rests where the controller's current holds the armature; the
        // feedforward leaves a small residual error (the flapper's own springs and
        // hydraulic forces), found by a few fixed-point passes (each contracts it by about
        // i_ff / K_p = 0.07).
        for _ in 0..6 {
            // spool force balance A_s (P_L - P_R) = 3 K_r x_r: the flapper angle holding it
            let residual = |th: f64| {
                let (pl, pr, _) = self.static_bridge(ps, pt, self.lfe * th);
                a * (pl - pr) - d.needle_stiffness * (xs - self.lre * th)
            };
            let span = 0.9 * d.nozzle_gap / self.lfe;
            let (mut lo, mut hi) = (-span, span);
            for _ in 0..60 {
                let m = 0.5 * (lo + hi);
                if residual(m) > 0.0 {
                    lo = m;
                } else {
                    hi = m;
                }
            }
            let th = 0.5 * (lo + hi);
            let (pl, pr, _) = self.static_bridge(ps, pt, self.lfe * th);
            let pf = self.pilot_flows(ps, pt, pl, pr, self.lfe * th);
            // torque balance (2.39) gives the coil current
            let xr = xs - self.lre * th;
            let f_hs = (pl - pr) * self.nozzle_area;
            let f_hd = self.env.density / self.nozzle_area * (pf.q_le.powi(2) - pf.q_re.powi(2));
            let i = -(self.kmr * th + d.needle_stiffness * xr * self.lre - d.tube_stiffness * th
                + (f_hs + f_hd) * self.lfe)
                / self.km;
            // the current loop holds it with u = R i; the controller's demand i_ref
            let i_ref = i + unsaturate(self.resistance * i, d.driver_voltage) / d.current_loop_gain;
            let z = -unsaturate(i_ref, d.current_limit);
            let e = (z - self.feedforward * s_ref) / d.position_gain;
            x[I_COIL] = i;
            x[THETA] = th;
            x[OMEGA] = 0.0;
            x[P_L] = pl;
            x[P_R] = pr;
            x[X_S] = xs;
            x[V_S] = 0.0;
            xs = (s_ref - e) * d.rated_stroke;
        }
    }

    /// Pressures of blocked ports A and B at spool position `xs` (Pa), from the land flow
    /// balances Q_A = Q_s1 - Q_s2 = 0 and Q_B = Q_s4 - Q_s3 = 0.
    pub fn blocked_port_pressures(&self, xs: f64, ps: f64, pt: f64) -> (f64, f64) {
        let solve = |port: usize| {
            let (mut lo, mut hi) = (pt, ps);
            for _ in 0..200 {
                let m = 0.5 * (lo + hi);
                let p = PortPressures {
                    supply: ps,
                    tank: pt,
                    a: m,
                    b: m,
                };
                let f = self.land_flows(xs, &p).q;
                // (2.40) flow leaving the port
                let q = if port == 0 { f[0] - f[1] } else { f[3] - f[2] };
                if q > 0.0 {
                    lo = m;
                } else {
                    hi = m;
                }
                if hi - lo < 1e-9 {
                    break;
                }
            }
            0.5 * (lo + hi)
        };
        (solve(0), solve(1))
    }

    /// Supply-to-tank leakage of the lands with both ports blocked (m3/s).
    pub fn blocked_port_leakage(&self, xs: f64, ps: f64, pt: f64) -> f64 {
        let (pa, pb) = self.blocked_port_pressures(xs, ps, pt);
        let f = self.land_flows(
            xs,
            &PortPressures {
                supply: ps,
                tank: pt,
                a: pa,
                b: pb,
            },
        );
        f.q[0] + f.q[3]
    }

    /// Flow through the valve with ports A and B joined by a lossless load (A -> load ->
    /// B), spool at `volts` of LVDT signal and `total_drop` (Pa) from P to T: the two
    /// metering lands in series, as the rated flow is specified (m3/s).
    pub fn load_flow(&self, volts: f64, total_drop: f64) -> f64 {
        let xs = volts / 10.0 * self.d.rated_stroke;
        let flows = |pm: f64| {
            let f = self.land_flows(
                xs,
                &PortPressures {
                    supply: total_drop,
                    tank: 0.0,
                    a: pm,
                    b: pm,
                },
            );
            // (2.40) Q_A, Q_B
            (f.q[0] - f.q[1], f.q[3] - f.q[2])
        };
        // the load pressure where what leaves A enters B: Q_A + Q_B = 0
        let (mut lo, mut hi) = (0.0, total_drop);
        for _ in 0..200 {
            let m = 0.5 * (lo + hi);
            let (qa, qb) = flows(m);
            if qa + qb > 0.0 {
                lo = m;
            } else {
                hi = m;
            }
        }
        flows(0.5 * (lo + hi)).0
    }

    /// Spool position in LVDT volts (10 V = rated stroke).
    pub fn spool_volts(&self, xs: f64) -> f64 {
        10.0 * xs / self.d.rated_stroke
    }
}

/// Smooth saturation of an amplifier stage at +-`limit`: linear to within 1e-4 up to a
/// tenth of the limit and to 3 % at half of it, unlike tanh, which already compresses by
/// 0.3 % at a tenth.
fn saturate(x: f64, limit: f64) -> f64 {
    x / (1.0 + (x / limit).powi(4)).powf(0.25)
}

/// Inverse of [`saturate`] for |y| < limit.
fn unsaturate(y: f64, limit: f64) -> f64 {
    let r = (y / limit).clamp(-0.999_999, 0.999_999);
    y / (1.0 - r.powi(4)).powf(0.25)
}

impl Servovalve for TwoStageServovalve {
    fn n_states(&self) -> usize {
        N_STATES
    }

    fn initial_state(&self, command: f64, x: &mut [f64]) {
        self.rest_state(command, self.env.supply, self.env.tank, x);
    }

    fn absolute_tolerances(&self, atol: &mut [f64]) {
        // about 1e-6 of each state's working range, like the bench's 1 Pa on 1e7 Pa; the
        // pilot pressures 1e-5 (100 Pa is 2.5 mN on the spool, against about 1 N of needle
        // force at full stroke): tighter only makes the solver follow the spool's ringing
        // on the pilot oil (see docs/servovalve.md) for longer
        atol[I_COIL] = 1e-7; // A, of up to 0.25 A
        atol[THETA] = 1e-9; // rad, of +-5e-3 rad
        atol[OMEGA] = 1e-5; // rad/s, of about 10 rad/s
        atol[P_L] = 100.0; // Pa, of 1e7 Pa
        atol[P_R] = 100.0;
        atol[X_S] = 1e-10; // m, of 4e-4 m
        atol[V_S] = 1e-7; // m/s, of 0.2 m/s
    }

    /// Dynamics with ports blocked: only leakage crosses the lands, so the spool flow force
    /// (2.43) is negligible (below 0.3 N against hundreds of newtons of pilot force) and
    /// left out; the pilot stage is fed from the supply given at construction.
    fn derivatives(&self, command: f64, x: &[f64], dx: &mut [f64]) {
        self.rhs(command, x, self.env.supply, self.env.tank, 0.0, dx);
    }

    fn derivatives_at(&self, command: f64, x: &[f64], p: &PortPressures, dx: &mut [f64]) {
        let f = self.land_flows(x[X_S], p);
        self.rhs(command, x, p.supply, p.tank, self.spool_flow_force(&f), dx);
    }

    fn spool_position(&self, _command: f64, x: &[f64]) -> f64 {
        x[X_S]
    }

    fn flows(&self, _command: f64, x: &[f64], p: &PortPressures) -> PortFlows {
        let f = self.land_flows(x[X_S], p);
        let pilot = self.pilot_flows(p.supply, p.tank, x[P_L], x[P_R], self.lfe * x[THETA]);
        // (2.40)
        PortFlows {
            a: f.q[0] - f.q[1],
            b: f.q[3] - f.q[2],
            // (2.40) metering lands from P, plus (2.1)-(2.2) the pilot inlets
            supply: f.q[0] + f.q[3] + pilot.q_pl + pilot.q_pr,
        }
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    fn valve() -> TwoStageServovalve {
        TwoStageServovalve::with_design(
            &ValveParams::default(),
            Design::default(),
            Environment::thesis_test(),
        )
    }

    /// d(P_A - P_B)/d(spool position in volts) with blocked ports (Pa/V).
    fn pressure_gain(v: &TwoStageServovalve, volts: f64) -> f64 {
        let (ps, pt) = (v.env.supply, v.env.tank);
        let dv = 0.002;
        let diff = |u: f64| {
            let (pa, pb) = v.blocked_port_pressures(u / 10.0 * v.d.rated_stroke, ps, pt);
            pa - pb
        };
        (diff(volts + dv) - diff(volts - dv)) / (2.0 * dv)
    }

    #[test]
    fn blocked_ports_pressure_gain_matches_the_thesis_model() {
        // Fig. 2.10(b): 827 bar/V (model), 850 bar/V (measured); 215/2 bar
        let v = valve();
        let g = pressure_gain(&v, 0.0) / BAR;
        println!("pressure gain at null: {g:.1} bar/V");
        assert!(
            (g / 827.0 - 1.0).abs() < 0.05,
            "pressure gain at null {g:.1} bar/V"
        );
        // the shape of Fig. 2.10(b): P_A rises from tank to supply over the plotted range,
        // P_B falls, P_A - P_B grows monotonically
        let (ps, pt) = (v.env.supply, v.env.tank);
        let mut prev = f64::NEG_INFINITY;
        for k in -40..=60 {
            let volts = 0.02 * k as f64;
            let (pa, pb) = v.blocked_port_pressures(volts / 10.0 * v.d.rated_stroke, ps, pt);
            assert!(pa - pb > prev, "P_A - P_B not increasing at {volts} V");
            prev = pa - pb;
        }
        let (pa, pb) = v.blocked_port_pressures(-0.08 * v.d.rated_stroke, ps, pt);
        assert!(
            pa < pt + 5.0 * BAR && pb > ps - 5.0 * BAR,
            "{pa} {pb} at -0.8 V"
        );
        let (pa, pb) = v.blocked_port_pressures(0.12 * v.d.rated_stroke, ps, pt);
        assert!(
            pa > ps - 5.0 * BAR && pb < pt + 5.0 * BAR,
            "{pa} {pb} at 1.2 V"
        );
    }

    #[test]
    fn blocked_ports_leakage_peaks_at_null() {
        let v = valve();
        let (ps, pt) = (v.env.supply, v.env.tank);
        let leak = |volts: f64| v.blocked_port_leakage(volts / 10.0 * v.d.rated_stroke, ps, pt);
        let grid: Vec<f64> = (-40..=60).map(|k| 0.02 * k as f64).collect();
        let q: Vec<f64> = grid.iter().map(|u| leak(*u)).collect();
        let k_max = (0..q.len()).max_by(|a, b| q[*a].total_cmp(&q[*b])).unwrap();
        println!(
            "leakage peak {:.3} L/min at {} V",
            q[k_max] / LPM,
            grid[k_max]
        );
        assert!(
            grid[k_max].abs() <= 0.04,
            "leakage peaks at {} V, not at null",
            grid[k_max]
        );
        // and falls on both sides of it
        for k in 1..q.len() {
            if k <= k_max {
                assert!(
                    q[k] >= q[k - 1],
                    "leakage not rising towards null at {} V",
                    grid[k]
                );
            } else {
                assert!(
                    q[k] <= q[k - 1],
                    "leakage not falling after null at {} V",
                    grid[k]
                );
            }
        }
        assert!(leak(0.8) < 0.5 * q[k_max] && leak(-0.8) < 0.5 * q[k_max]);
    }

    #[test]
    fn rated_flow_at_rated_command_and_70_bar() {
        // Table 1.1: 19 L/min at 70 bar total drop (two lands in series) and 10 V
        let v = valve();
        let q = v.load_flow(10.0, 70.0 * BAR) / LPM;
        println!("rated flow {q:.2} L/min");
        assert!((q / 19.0 - 1.0).abs() < 0.05, "rated flow {q:.2} L/min");
        let q_neg = -v.load_flow(-10.0, 70.0 * BAR) / LPM;
        println!("rated flow at -10 V {q_neg:.2} L/min");
        assert!(
            (q_neg / 19.0 - 1.0).abs() < 0.05,
            "rated flow at -10 V {q_neg:.2} L/min"
        );
    }

    #[test]
    fn rest_state_is_an_equilibrium() {
        let v = valve();
        for command in [0.0, 4.0, -10.0, 10.0] {
            let mut x = vec![0.0; N_STATES];
            v.initial_state(command, &mut x);
            let mut dx = vec![0.0; N_STATES];
            v.derivatives(command, &x, &mut dx);
            let mut atol = vec![0.0; N_STATES];
            v.absolute_tolerances(&mut atol);
            // the proportional electronics with the calibrated feedforward leave a static
            // error below 0.1 % of the stroke (the flapper's own springs and hydraulic forces)
            let error = x[X_S] / v.d.rated_stroke - command / 10.0;
            println!("static error at {command} V: {error:.2e} of the stroke");
            assert!(
                error.abs() < 1e-3,
                "spool {error} of the stroke off at {command} V"
            );
            // every rate below what one atol per microsecond would be
            for i in 0..N_STATES {
                assert!(
                    dx[i].abs() < atol[i] * 1e6,
                    "state {i}: {} at {command} V",
                    dx[i]
                );
            }
        }
    }

    /// Frequency where a sampled curve first crosses `level` downwards, interpolated in
    /// log frequency; None when it does not cross within the grid.
    fn crossing(points: &[(f64, f64)], level: f64) -> Option<f64> {
        points.windows(2).find_map(|w| {
            let ((f0, y0), (f1, y1)) = (w[0], w[1]);
            (y0 >= level && y1 < level).then(|| {
                let s = (y0 - level) / (y0 - y1);
                (f0.ln() + s * (f1.ln() - f0.ln())).exp()
            })
        })
    }

    /// (-3 dB, -90 deg) frequencies of the spool position at `amplitude`, found on `grid`.
    fn bandwidths(
        v: &TwoStageServovalve,
        amplitude: f64,
        grid: &[f64],
    ) -> (Option<f64>, Option<f64>) {
        let mut gain = Vec::new();
        let mut phase = Vec::new();
        for f in grid {
            let h = sine_response(v, amplitude, *f, 4, 2, 1e-6).expect("the valve integrates");
            println!(
                "  {amplitude} {f} Hz: {:.2} dB {:.1} deg",
                20.0 * h.gain.log10(),
                h.phase_deg
            );
            gain.push((*f, 20.0 * h.gain.log10()));
            phase.push((*f, h.phase_deg));
        }
        (crossing(&gain, -3.0), crossing(&phase, -90.0))
    }

    #[test]
    fn frequency_response_matches_the_manufacturer() {
        // Fig. 2.3 / Table 1.1: about 310 Hz at 40 % and 160 Hz at 90-100 % input; ports
        // blocked, 215/2 bar. Each grid reaches past the +-25 % band on both sides.
        let v = valve();
        for (amplitude, target, grid) in [
            (
                0.4,
                310.0,
                &[200.0, 230.0, 260.0, 290.0, 320.0, 350.0, 400.0, 450.0][..],
            ),
            (
                1.0,
                160.0,
                &[100.0, 115.0, 130.0, 145.0, 160.0, 180.0, 205.0, 240.0][..],
            ),
        ] {
            let (f3, f90) = bandwidths(&v, amplitude, grid);
            let f3 = f3.unwrap_or_else(|| panic!("no -3 dB crossing at {amplitude} in {grid:?}"));
            let f90 =
                f90.unwrap_or_else(|| panic!("no -90 deg crossing at {amplitude} in {grid:?}"));
            println!(
                "{} %: -3 dB at {f3:.0} Hz, -90 deg at {f90:.0} Hz",
                amplitude * 100.0
            );
            assert!(
                (f3 / target - 1.0).abs() < 0.25,
                "-3 dB at {} %: {f3:.0} Hz",
                amplitude * 100.0
            );
            assert!(
                (f90 / target - 1.0).abs() < 0.25,
                "-90 deg at {} %: {f90:.0} Hz",
                amplitude * 100.0
            );
        }
    }

    #[test]
    fn bandwidth_loss_at_large_input_is_the_pilot_stage_flow_saturating() {
        let v = valve();
        // small input: no loss at 160 Hz, the flapper far from its nozzles
        let small = sine_response(&v, 0.05, 160.0, 4, 2, 1e-6).unwrap();
        assert!(20.0 * small.gain.log10() > -1.0, "{small:?}");
        assert!(small.seated_fraction == 0.0, "{small:?}");
        // full input: the flapper seats on its nozzles, so the pilot flow is at its
        // ceiling (the upstream orifice's), and the response drops
        let full = sine_response(&v, 1.0, 160.0, 4, 2, 1e-6).unwrap();
        assert!(full.seated_fraction > 0.2, "{full:?}");
        assert!(20.0 * full.gain.log10() < -2.0, "{full:?}");
        // the electronics' limits are not what sets the loss: without the driver's current
        // and voltage limits the amplitude ratio barely moves
        let d = Design {
            driver_voltage: 1e4,
            current_limit: 1e2,
            ..Design::default()
        };
        let unlimited = TwoStageServovalve::with_design(&ValveParams::default(), d, v.env);
        let free = sine_response(&unlimited, 1.0, 160.0, 4, 2, 1e-6).unwrap();
        let change = 20.0 * (free.gain / full.gain).log10();
        println!(
            "100 % at 160 Hz: {:.2} dB, flapper seated {:.0} % of the time; without driver limits {change:+.2} dB",
            20.0 * full.gain.log10(),
            100.0 * full.seated_fraction
        );
        assert!(change.abs() < 0.5, "{change} dB without the driver limits");
        // while a pilot stage passing 40 % more flow (larger inlet orifices and nozzles,
        // same bridge ratio) moves the spool faster and loses less
        let d = Design {
            inlet_diameter: INLET_DIAMETER * 1.4f64.sqrt(),
            nozzle_gap: NOZZLE_GAP * 1.4,
            ..Design::default()
        };
        let bigger = TwoStageServovalve::with_design(&ValveParams::default(), d, v.env);
        let more = sine_response(&bigger, 1.0, 160.0, 4, 2, 1e-6).unwrap();
        assert!(more.gain > 1.15 * full.gain, "{more:?} vs {full:?}");
    }

    #[test]
    fn selected_by_parameter_file_and_steps_the_bench_like_the_reduced_valve() {
        use crate::control::{response_time_95, run_closed_loop, Proportional, SAMPLE_PERIOD};
        use crate::params::{Mode, ValveModel};
        let text = "[sv1]\nmodel = \"two_stage\"\n[sv2]\nmodel = \"two_stage\"\n";
        let p = Params::from_toml_named(text, "two_stage.toml").unwrap();
        assert_eq!(p.sv1.model, ValveModel::TwoStage);
        assert!(p.to_toml().contains("model = \"two_stage\""));
        // section 4.4: proportional control Kp = 1169 V/m, -10 -> +10 mm, mode 3
        let t95 = |model: ValveModel| {
            let mut p = Params::thesis_bench(Mode::ThreeWay);
            p.sv1.model = model;
            p.sv2.model = model;
            p.initial_position = -0.01;
            let mut sim = crate::Simulation::new(&p).unwrap();
            let tr = run_closed_loop(
                &mut sim,
                &mut Proportional { kp: 1169.0 },
                &|_| 0.01,
                0.12,
                SAMPLE_PERIOD,
                1,
            )
            .expect("the bench integrates");
            (
                response_time_95(&tr, 0.0, -0.01, 0.01).unwrap(),
                sim.bench().n_states(),
            )
        };
        let (reduced, n_reduced) = t95(ValveModel::Reduced);
        let (physical, n_physical) = t95(ValveModel::TwoStage);
        assert_eq!(n_physical, n_reduced + 2 * (N_STATES - 2));
        println!("95 % step time: reduced {reduced:.4} s, two-stage {physical:.4} s");
        assert!(
            (physical / reduced - 1.0).abs() < 0.1,
            "{physical} vs {reduced} s"
        );
    }
}
