//! The two-stage valve's exact Jacobian, derivative by derivative of `dynamics.rs`.
//!
//! The pilot pressure P_E is the root of the flapper chamber's balance (2.5),
//! F(P_E; P_L, P_R, P_T, x_f) = 0, so its derivatives follow from the implicit function
//! theorem, dP_E/dv = -(dF/dv)/(dF/dP_E). The land flows and flow forces differentiate
//! through `lands` (the jet angle through its Hermite table). Smooth saturations and the
//! seat contact take the derivative of the branch the right-hand side evaluates.

use super::electronics::saturate;
use super::pilot::{NOZZLE_SEAT_ROUGHNESS, PILOT_LAMINAR_DP, SEAT_DAMPING, SEAT_STIFFNESS};
use super::spool::LandFlows;
use super::*;
use crate::fluid::{signed_sqrt, signed_sqrt_slope};
use crate::jacobian::Jacobian;
use crate::servovalve::port::{P_A, P_B, P_S, P_T, Q_A, Q_B, Q_S, U, X_S as OUT_X_S};
use crate::servovalve::PortPressures;

/// d(saturate)/dx = (1 + (x/L)^4)^(-5/4).
fn saturate_slope(x: f64, limit: f64) -> f64 {
    (1.0 + (x / limit).powi(4)).powf(-1.25)
}

/// A gradient over the variables a pilot quantity depends on.
#[derive(Debug, Clone, Copy, Default)]
struct Grad {
    pl: f64,
    pr: f64,
    ps: f64,
    pt: f64,
    /// flapper position x_f = l_fe theta
    xf: f64,
}

impl Grad {
    fn scale(self, k: f64) -> Grad {
        Grad {
            pl: self.pl * k,
            pr: self.pr * k,
            ps: self.ps * k,
            pt: self.pt * k,
            xf: self.xf * k,
        }
    }
    fn add(self, o: Grad) -> Grad {
        Grad {
            pl: self.pl + o.pl,
            pr: self.pr + o.pr,
            ps: self.ps + o.ps,
            pt: self.pt + o.pt,
            xf: self.xf + o.xf,
        }
    }
}

/// Derivatives of the nozzle flows Q_LE, Q_RE and the inlet flows Q_PL, Q_PR.
struct PilotSlopes {
    q_le: Grad,
    q_re: Grad,
    q_pl: Grad,
    q_pr: Grad,
}

impl TwoStageServovalve {
    /// d(gap)/dx_f of the left and right nozzle gaps (the soft floor's slope).
    fn gap_slopes(&self, xf: f64) -> (f64, f64) {
        let e = NOZZLE_SEAT_ROUGHNESS;
        let soft = |g: f64| 0.5 * (1.0 + g / (g * g + e * e).sqrt());
        (soft(self.d.nozzle_gap + xf), -soft(self.d.nozzle_gap - xf))
    }

    fn pilot_slopes(&self, ps: f64, pt: f64, pl: f64, pr: f64, xf: f64) -> PilotSlopes {
        let t = PILOT_LAMINAR_DP;
        let ss = |p: f64| signed_sqrt(p, t);
        let dss = |p: f64| signed_sqrt_slope(p, t);
        let pf = self.pilot_flows(ps, pt, pl, pr, xf);
        let pe = pf.p_e;
        let (gl, gr) = self.gaps(xf);
        let (dgl, dgr) = self.gap_slopes(xf);
        let (kl, kr, kd, nk) = (
            self.nozzle_k * gl,
            self.nozzle_k * gr,
            self.drain_k,
            self.nozzle_k,
        );
        // (2.5) F = kl ss(PL - PE) + kr ss(PR - PE) - kd ss(PE - PT) = 0
        let (sl, sr, sd) = (dss(pl - pe), dss(pr - pe), dss(pe - pt));
        let f_pe = -kl * sl - kr * sr - kd * sd;
        let f = Grad {
            pl: kl * sl,
            pr: kr * sr,
            ps: 0.0,
            pt: kd * sd,
            xf: nk * dgl * ss(pl - pe) + nk * dgr * ss(pr - pe),
        };
        let d_pe = f.scale(-1.0 / f_pe);
        // (2.3)-(2.4) Q_LE = kl ss(PL - PE), Q_RE = kr ss(PR - PE)
        let q_le = Grad {
            pl: kl * sl,
            xf: nk * dgl * ss(pl - pe),
            ..Grad::default()
        }
        .add(d_pe.scale(-kl * sl));
        let q_re = Grad {
            pr: kr * sr,
            xf: nk * dgr * ss(pr - pe),
            ..Grad::default()
        }
        .add(d_pe.scale(-kr * sr));
        // (2.1)-(2.2) Q_PL = k ss(PS - PL), Q_PR = k ss(PS - PR)
        let il = self.inlet_k * dss(ps - pl);
        let ir = self.inlet_k * dss(ps - pr);
        PilotSlopes {
            q_le,
            q_re,
            q_pl: Grad {
                ps: il,
                pl: -il,
                ..Grad::default()
            },
            q_pr: Grad {
                ps: ir,
                pr: -ir,
                ..Grad::default()
            },
        }
    }

    /// d(seat_force)/dx_f and d(seat_force)/dv_f.
    fn seat_force_slopes(&self, xf: f64, vf: f64) -> (f64, f64) {
        let left = (-(self.d.nozzle_gap + xf)).max(0.0);
        let right = (-(self.d.nozzle_gap - xf)).max(0.0);
        let d_left = if left > 0.0 { -1.0 } else { 0.0 };
        let d_right = if right > 0.0 { 1.0 } else { 0.0 };
        (
            SEAT_STIFFNESS
                * (1.5 * left.sqrt() * d_left * (1.0 - SEAT_DAMPING * vf)
                    - 1.5 * right.sqrt() * d_right * (1.0 + SEAT_DAMPING * vf)),
            -SEAT_STIFFNESS * SEAT_DAMPING * (left.powf(1.5) + right.powf(1.5)),
        )
    }
}

/// Each land's opening sign in x_s and its drop's (P_S, P_T, P_A, P_B) coefficients.
const LAND_SIGNS: [f64; 4] = [1.0, -1.0, 1.0, -1.0];
const LAND_DROPS: [[f64; 4]; 4] = [
    [1.0, 0.0, -1.0, 0.0], // P -> A
    [0.0, -1.0, 1.0, 0.0], // A -> T
    [0.0, -1.0, 0.0, 1.0], // B -> T
    [1.0, 0.0, 0.0, -1.0], // P -> B
];
const PORT_INPUTS: [usize; 4] = [P_S, P_T, P_A, P_B];

pub(super) fn exact(
    v: &TwoStageServovalve,
    command: f64,
    x: &[f64],
    p: &PortPressures,
    jac: &mut Jacobian,
) {
    let d = &v.d;
    let (i, th, om) = (x[I_COIL], x[THETA], x[OMEGA]);
    let (pl, pr, xs, vs) = (x[P_L], x[P_R], x[X_S], x[V_S]);
    let (ps, pt) = (p.supply, p.tank);

    // lands: dq_k/dx_s and dq_k/d(drop), flow forces
    let lands: LandFlows = v.land_flows(xs, p);
    let l = &v.lands;
    let drops = [ps - p.a, p.a - pt, p.b - pt, ps - p.b];
    let mut dq_dxs = [0.0; 4];
    let mut dq_ddp = [0.0; 4];
    let mut dforce_dxs = 0.0;
    let mut dforce_dport = [0.0; 4];
    // (2.43) f_flow = F_2 - F_1 + F_4 - F_3
    let force_sign = [-1.0, 1.0, -1.0, 1.0];
    for k in 0..4 {
        let (qx, qdp) = l.flow_slopes(lands.x[k], drops[k]);
        dq_dxs[k] = qx * LAND_SIGNS[k];
        dq_ddp[k] = qdp;
        let (fx, fq) = l.flow_force_slopes(lands.x[k], lands.q[k]);
        dforce_dxs += force_sign[k] * (fx * LAND_SIGNS[k] + fq * dq_dxs[k]);
        for (j, c) in LAND_DROPS[k].iter().enumerate() {
            dforce_dport[j] += force_sign[k] * fq * qdp * c;
        }
    }

    // outputs (2.40): Q_A = q1 - q2, Q_B = q4 - q3, Q_P = q1 + q4 + Q_PL + Q_PR
    let xf = v.lfe * th;
    let ps_ = v.pilot_slopes(ps, pt, pl, pr, xf);
    let out_lands: [(usize, [f64; 4]); 3] = [
        (Q_A, [1.0, -1.0, 0.0, 0.0]),
        (Q_B, [0.0, 0.0, -1.0, 1.0]),
        (Q_S, [1.0, 0.0, 0.0, 1.0]),
    ];
    for (o, w) in out_lands {
        for k in 0..4 {
            *jac.yx(o, X_S) += w[k] * dq_dxs[k];
            for (j, c) in LAND_DROPS[k].iter().enumerate() {
                *jac.yu(o, PORT_INPUTS[j]) += w[k] * dq_ddp[k] * c;
            }
        }
    }
    let inlet = ps_.q_pl.add(ps_.q_pr);
    *jac.yx(Q_S, P_L) += inlet.pl;
    *jac.yx(Q_S, P_R) += inlet.pr;
    *jac.yu(Q_S, P_S) += inlet.ps;
    *jac.yx(OUT_X_S, X_S) = 1.0;

    // electronics and coils (2.48)
    let s_ref = v.reference(command);
    let ds_ref = if ((command - v.null_bias) / v.rated_command).abs() < 1.0 {
        1.0 / v.rated_command
    } else {
        0.0
    };
    let e = s_ref - xs / d.rated_stroke;
    let z1 = d.position_gain * e + v.feedforward * s_ref;
    let i_ref = -saturate(z1, d.current_limit);
    let z2 = d.current_loop_gain * (i_ref - i);
    let du = saturate_slope(z2, d.driver_voltage) * d.current_loop_gain;
    let di_ref = -saturate_slope(z1, d.current_limit);
    *jac.fx(I_COIL, I_COIL) = (-du - v.resistance) / v.inductance;
    *jac.fx(I_COIL, OMEGA) = -v.back_emf / v.inductance;
    *jac.fx(I_COIL, X_S) = du * di_ref * (-d.position_gain / d.rated_stroke) / v.inductance;
    *jac.fu(I_COIL, U) = du * di_ref * (d.position_gain + v.feedforward) * ds_ref / v.inductance;

    // pilot chambers (2.6)-(2.7)
    let a = v.spool_area;
    let v0 = d.pilot_chamber_volume;
    let beta = v.env.bulk_modulus;
    let pf = v.pilot_flows(ps, pt, pl, pr, xf);
    for (row, sign, q_in, q_out) in [
        (P_L, 1.0, ps_.q_pl, ps_.q_le),
        (P_R, -1.0, ps_.q_pr, ps_.q_re),
    ] {
        let vol = v0 + sign * a * xs;
        let k = beta / vol;
        let net = if row == P_L {
            pf.q_pl - pf.q_le - a * vs
        } else {
            pf.q_pr - pf.q_re + a * vs
        };
        let g = q_in.add(q_out.scale(-1.0));
        *jac.fx(row, X_S) = -k * sign * a / vol * net;
        *jac.fx(row, V_S) = -k * sign * a;
        *jac.fx(row, P_L) = k * g.pl;
        *jac.fx(row, P_R) = k * g.pr;
        *jac.fx(row, THETA) = k * g.xf * v.lfe;
        *jac.fu(row, P_S) = k * g.ps;
        *jac.fu(row, P_T) = k * g.pt;
    }

    // armature (2.39)
    let (seat_x, seat_v) = v.seat_force_slopes(xf, v.lfe * om);
    let rho_a = v.env.density / v.nozzle_area;
    let f_hd = ps_
        .q_le
        .scale(2.0 * rho_a * pf.q_le)
        .add(ps_.q_re.scale(-2.0 * rho_a * pf.q_re));
    let jm = d.armature_inertia;
    let lfe = v.lfe;
    *jac.fx(THETA, OMEGA) = 1.0;
    *jac.fx(OMEGA, I_COIL) = v.km / jm;
    *jac.fx(OMEGA, THETA) = (v.kmr - d.needle_stiffness * v.lre * v.lre - d.tube_stiffness
        + lfe * (f_hd.xf + seat_x) * lfe)
        / jm;
    *jac.fx(OMEGA, OMEGA) = (lfe * seat_v * lfe - d.armature_damping) / jm;
    *jac.fx(OMEGA, X_S) = d.needle_stiffness * v.lre / jm;
    *jac.fx(OMEGA, P_L) = lfe * (v.nozzle_area + f_hd.pl) / jm;
    *jac.fx(OMEGA, P_R) = lfe * (-v.nozzle_area + f_hd.pr) / jm;
    *jac.fu(OMEGA, P_S) = lfe * f_hd.ps / jm;
    *jac.fu(OMEGA, P_T) = lfe * f_hd.pt / jm;

    // spool (2.41)-(2.42)
    let ms = d.spool_mass;
    let bs = d.spool_damping_centre + d.spool_damping_slope * xs.abs();
    *jac.fx(X_S, V_S) = 1.0;
    *jac.fx(V_S, P_L) = a / ms;
    *jac.fx(V_S, P_R) = -a / ms;
    *jac.fx(V_S, THETA) = d.needle_stiffness * v.lre / ms;
    *jac.fx(V_S, X_S) =
        (-d.needle_stiffness - d.spool_damping_slope * xs.signum() * vs + dforce_dxs) / ms;
    *jac.fx(V_S, V_S) = -bs / ms;
    for (j, df) in dforce_dport.iter().enumerate() {
        *jac.fu(V_S, PORT_INPUTS[j]) += df / ms;
    }
}
