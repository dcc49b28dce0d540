//! The two multivariable backstepping laws of chapter 5 (section 5.3), written on the
//! control model (II.1)-(II.2) / (5.13)-(5.14):
//!
//! ```text
//! dy/dt  = v
//! dv/dt  = A/M (P1 - P2) - g - b/M v                     (dry friction and F_ext: see below)
//! dP1/dt = -beta/V1(y) A v + beta/V1(y) phi1(P1, sign u1) u1,   V1 = V0 + A y
//! dP2/dt = +beta/V2(y) A v + beta/V2(y) phi2(P2, sign u2) u2,   V2 = V0 - A y
//! phi_i  = Qn/un sqrt(|PP - Pi|/dPn)  if u_i > 0,   Qn/un sqrt(|Pi - PT|/dPn)  if u_i < 0
//! ```
//!
//! * [`YLambda`] (5.16)-(5.35): position tracking plus a distribution of the chamber
//!   pressures around P0 with the weight lambda (5.15), P1 = P0 + lambda dP,
//!   P2 = P0 + (lambda - 1) dP, i.e. (1 - lambda) P1 + lambda P2 = P0.
//! * [`PY`] (5.36)-(5.58): chamber-1 pressure tracks P1d with u1, position tracks y_d
//!   with u2 through the third-order chain (y, v, a).
//!
//! Both take their pressure reference (P0 for Y-lambda, P1d for P-Y) and its derivative
//! from [`Reference::p`]; the thesis uses 80 bar for both ([`P_REF_THESIS`]).
//!
//! Choices the thesis leaves open or that differ from its text:
//! * Dry friction. The thesis keeps F_fs (4.13) and dF_fs/dv in (5.26), (5.30), (5.36);
//!   [`ControlModel`] carries no dry-friction data and the bench's hydrostatic bearings make
//!   it small (the thesis neglects it in its own equilibrium analysis, (7.1)), so only the
//!   viscous term b v is compensated. F_ext is not measured by the laws and is taken as 0.
//! * sign(u_i) in phi_i. Because 1/g_i > 0, the sign of u_i is the sign of the bracket
//!   the law divides by g_i (the demanded flow); the thesis's notes under (5.34), (5.41)
//!   and (5.57) say the same. Evaluating phi_i with that sign is exact, needs no memory of
//!   the previous command and has no algebraic loop. The previous command's sign would lag
//!   by one sample exactly when the flow reverses, i.e. pick the wrong land's pressure drop
//!   at each reversal (end of every move), which is where the Y-lambda pressures are stiff.
//! * The P-Y command u2 compensates the flow of u1 (5.57); it uses u1 as the valve will
//!   receive it (saturated), since an unsaturated u1 would be compensated for flow that
//!   never enters chamber 1.

use super::law::{ControlModel, Estimate, Law, Reference};
use super::COMMAND_LIMIT;

/// Gravitational acceleration (m/s2) of (II.1); the actuator is vertical, y upwards.
pub const GRAVITY: f64 = 9.81;

/// Pressure reference of the thesis's simulations and experiments (Pa absolute): P0 of
/// Y-lambda and P1d of P-Y, section 5.5 (80 bar, below the ~110 bar the chambers settle
/// at without pressure control, to change the stiffness).
pub const P_REF_THESIS: f64 = 80e5;

/// Weight lambda of the thesis (section 5.5): equal share of dP between the chambers.
pub const LAMBDA_THESIS: f64 = 0.5;

pub use super::law::MIN_LAND_DROP;

/// The four backstepping gains c1..c4 (1/s).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Gains {
    pub c1: f64,
    pub c2: f64,
    pub c3: f64,
    pub c4: f64,
}

impl Gains {
    /// Section 5.5 simulation gains, both laws.
    pub const LOW: Gains = Gains {
        c1: 500.0,
        c2: 400.0,
        c3: 400.0,
        c4: 400.0,
    };
    /// Section 5.6.2 high gains of the Y-lambda law.
    pub const HIGH_Y_LAMBDA: Gains = Gains {
        c1: 700.0,
        c2: 600.0,
        c3: 700.0,
        c4: 700.0,
    };
    /// Section 5.6.2 high gains of the P-Y law.
    pub const HIGH_P_Y: Gains = Gains {
        c1: 700.0,
        c2: 600.0,
        c3: 600.0,
        c4: 700.0,
    };
}

/// Command u = bracket / g with g = beta/V phi(P, sign u) > 0: sign(u) = sign(bracket).
fn invert_flow(m: &ControlModel, volume: f64, p: f64, bracket: f64) -> f64 {
    let g = m.bulk_modulus / volume * m.flow_gain(p, bracket);
    bracket / g
}

/// Errors and commands of one evaluation, kept together so tests can check the error
/// dynamics the law is meant to impose.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Step {
    e: [f64; 4],
    u: [f64; 2],
}

/// Backstepping Y-lambda law, (5.16)-(5.35).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct YLambda {
    pub model: ControlModel,
    pub gains: Gains,
    /// Dynamic weight lambda of (5.15), held constant (d lambda/dt = 0) as in the
    /// thesis's simulations and experiments.
    pub lambda: f64,
}

impl YLambda {
    pub fn new(model: ControlModel, gains: Gains, lambda: f64) -> Self {
        Self {
            model,
            gains,
            lambda,
        }
    }

    /// The pressure combination the law holds at P0: (1 - lambda) P1 + lambda P2, from
    /// (5.15) (it eliminates dP).
    pub fn pressure_combination(&self, p1: f64, p2: f64) -> f64 {
        (1.0 - self.lambda) * p1 + self.lambda * p2
    }

    fn step(&self, r: &Reference, x: &Estimate) -> Step {
        let m = &self.model;
        let Gains { c1, c2, c3, c4 } = self.gains;
        let lambda = self.lambda;
        let (area, mass, b) = (m.area, m.mass, m.viscous);
        let [yd, vd, ad, jd] = r.y;
        let [p0, p0_dot] = r.p;

        // (5.16), (5.22): e2 is the velocity's departure from the virtual control (5.20)
        let e1 = x.y - yd;
        let e2 = x.v - vd + c1 * e1;
        // (5.26) virtual control dP = alpha1: the pressure difference that makes
        // de2/dt = -c2 e2 - e1 (the printed "(c1 - 1)" is c1^2 - 1 with its exponent lost)
        let alpha1 =
            mass / area * (ad + b / mass * x.v + GRAVITY + (c1 * c1 - 1.0) * e1 - (c1 + c2) * e2);
        // (5.28)-(5.29): dP is shared between the chambers around P0 by lambda (5.15)
        let e3 = x.p1 - p0 - lambda * alpha1;
        let e4 = x.p2 - p0 - (lambda - 1.0) * alpha1;
        // (5.30) d(alpha1)/dt: de2/dt is taken from the model (A/M (e3 - e4) - c2 e2 - e1)
        // and d(b v)/dt from the acceleration estimate, as printed
        let alpha1_dot = mass / area
            * (jd + b / mass * x.a - (c1 * c1 * c1 - 2.0 * c1 - c2) * e1
                + (c1 * c1 + c1 * c2 + c2 * c2 - 1.0) * e2
                - (c1 + c2) * area / mass * (e3 - e4));
        let (v1, v2) = m.volumes(x.y);
        // (5.30) drift of the pressure equations
        let f1 = -m.bulk_modulus / v1 * area * x.v;
        let f2 = m.bulk_modulus / v2 * area * x.v;
        // (5.33)-(5.34): the +-A/M e2 terms cancel the cross term e2 (A/M)(e3 - e4) of
        // (5.32) so that (5.35) dV3/dt = -sum c_i e_i^2; d(lambda)/dt alpha1 = 0
        let k = area / mass;
        let q1 = -f1 + p0_dot + lambda * alpha1_dot - k * e2 - c3 * e3;
        let q2 = -f2 + p0_dot + (lambda - 1.0) * alpha1_dot + k * e2 - c4 * e4;
        Step {
            e: [e1, e2, e3, e4],
            u: [invert_flow(m, v1, x.p1, q1), invert_flow(m, v2, x.p2, q2)],
        }
    }
}

impl Law for YLambda {
    fn commands(&mut self, _t: f64, reference: &Reference, x: &Estimate, _period: f64) -> [f64; 2] {
        self.step(reference, x).u
    }
}

/// Backstepping P-Y law, (5.36)-(5.58).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PY {
    pub model: ControlModel,
    pub gains: Gains,
}

impl PY {
    pub fn new(model: ControlModel, gains: Gains) -> Self {
        Self { model, gains }
    }

    fn step(&self, r: &Reference, x: &Estimate) -> Step {
        let m = &self.model;
        let Gains { c1, c2, c3, c4 } = self.gains;
        let (area, mass, b, beta) = (m.area, m.mass, m.viscous, m.bulk_modulus);
        let [yd, vd, ad, jd] = r.y;
        let [p1d, p1d_dot] = r.p;
        let (v1, v2) = m.volumes(x.y);

        // (5.37)-(5.41): chamber 1 alone is a first-order system in u1; cancel the
        // piston-motion term and impose de4/dt = -c4 e4
        let e4 = x.p1 - p1d;
        let u1 = invert_flow(m, v1, x.p1, beta / v1 * area * x.v + p1d_dot - c4 * e4);

        // (5.42), (5.47): as in Y-lambda, but the chain goes on to the acceleration (5.36)
        let e1 = x.y - yd;
        let e2 = x.v - vd + c1 * e1;
        // (5.51) virtual acceleration, (5.53) its error
        let alpha1 = ad + (c1 * c1 - 1.0) * e1 - (c1 + c2) * e2;
        let e3 = x.a - alpha1;
        // (5.57) gains: da/dt = d(alpha1)/dt - e2 - c3 e3 written on e1, e2, e3
        let k1 = 2.0 * c1 + c2 - c1 * c1 * c1;
        let k2 = c1 * c1 + c1 * c2 + c2 * c2 - 2.0;
        let k3 = -(c1 + c2 + c3);
        // (5.36) drift of da/dt. No g: gravity is constant and drops out of da/dt, so a
        // wrong mass only mis-scales this loop's gains instead of shifting its
        // equilibrium as M_hat g does in Y-lambda's (5.26) (Table 7.1)
        let f = -b / mass * x.a - area * area * beta / mass * (1.0 / v1 + 1.0 / v2) * x.v;
        let g1 = beta / v1 * m.flow_gain(x.p1, u1);
        let u1_applied = u1.clamp(-COMMAND_LIMIT, COMMAND_LIMIT);
        // (5.57) u2 = -M/(A g2) * bracket; -M/(A g2) < 0 so sign(u2) = -sign(bracket)
        let bracket = -f - area * g1 / mass * u1_applied + jd + k1 * e1 + k2 * e2 + k3 * e3;
        let u2 = mass / area * invert_flow(m, v2, x.p2, -bracket);
        Step {
            e: [e1, e2, e3, e4],
            u: [u1, u2],
        }
    }
}

impl Law for PY {
    fn commands(&mut self, _t: f64, reference: &Reference, x: &Estimate, _period: f64) -> [f64; 2] {
        self.step(reference, x).u
    }
}

#[cfg(test)]
mod tests;
