//! Flapper-nozzle pilot stage (2.1)-(2.8): two fixed inlet orifices, the two nozzles
//! the flapper throttles, the drain of the flapper chamber, and the nozzle seats that
//! are the flapper's travel stops.

use super::TwoStageServovalve;
use crate::params::BAR;
use crate::servovalve::signed_sqrt;

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

/// Flows of the pilot bridge (m3/s) and the flapper chamber pressure P_E (Pa).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PilotFlows {
    pub q_pl: f64,
    pub q_pr: f64,
    pub q_le: f64,
    pub q_re: f64,
    pub p_e: f64,
}

impl TwoStageServovalve {
    /// Nozzle gaps x_f0 +- x_f, kept positive through the seat roughness when the flapper
    /// seats on a nozzle.
    pub(super) fn gaps(&self, xf: f64) -> (f64, f64) {
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

    /// Contact force of the nozzles on the flapper (N), positive towards +x_f: Hertz with
    /// Hunt-Crossley damping, zero while the flapper is clear of both nozzles.
    pub(super) fn seat_force(&self, xf: f64, vf: f64) -> f64 {
        let left = (-(self.d.nozzle_gap + xf)).max(0.0); // penetration into the left nozzle
        let right = (-(self.d.nozzle_gap - xf)).max(0.0);
        SEAT_STIFFNESS
            * (left.powf(1.5) * (1.0 - SEAT_DAMPING * vf)
                - right.powf(1.5) * (1.0 + SEAT_DAMPING * vf))
    }

    /// Static pilot bridge (no chamber flow) at flapper position x_f: (P_L, P_R, P_E).
    pub(super) fn static_bridge(&self, ps: f64, pt: f64, xf: f64) -> (f64, f64, f64) {
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
}
