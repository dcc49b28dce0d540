//! The actuator as a component: a capacity and an inertance, the chamber inflows and the
//! external force in, the chamber pressures out (section 4.1).

use super::{oil_stiffness_slope, Component, Jacobian, Port, Signature, State};
use crate::actuator::{Actuator, END_STOP_DAMPING, END_STOP_STIFFNESS};
use crate::fluid::oil_stiffness;
use crate::fluid::FluidParams;
use crate::friction::dry_friction_slope;
use crate::params::LPM;

/// States.
pub const Y: usize = 0;
pub const V: usize = 1;
pub const P1: usize = 2;
pub const P2: usize = 3;
/// Input ports: flows delivered into the chambers, the external force.
pub const Q1: usize = 0;
pub const Q2: usize = 1;
pub const F_EXT: usize = 2;
/// Output ports: the chamber pressures.
pub const OUT_P1: usize = 0;
pub const OUT_P2: usize = 1;

/// The actuator with the oil that fills it.
#[derive(Debug, Clone)]
pub struct ActuatorComponent {
    pub actuator: Actuator,
    fluid: FluidParams,
    air: bool,
    tank: f64,
    signature: Signature,
}

impl ActuatorComponent {
    /// `air`: entrained air in the oil; `tank`: the drain pressure of the leakage (Pa).
    pub fn new(actuator: Actuator, fluid: FluidParams, air: bool, tank: f64) -> Self {
        ActuatorComponent {
            actuator,
            fluid,
            air,
            tank,
            signature: Signature {
                // 1 nm, 1 um/s, 1 Pa: well below the sensors' resolution
                states: vec![
                    State::new("y", "m", 1e-9, 1e-3),
                    State::new("v", "m/s", 1e-6, 1e-2),
                    State::new("P1", "Pa", 1.0, 1e6),
                    State::new("P2", "Pa", 1.0, 1e6),
                ],
                inputs: vec![
                    Port::new("Q1", "m3/s"),
                    Port::new("Q2", "m3/s"),
                    Port::new("F_ext", "N"),
                ],
                outputs: vec![Port::new("P1", "Pa"), Port::new("P2", "Pa")],
            },
        }
    }

    /// Effective bulk modulus of the oil at pressure p.
    pub fn stiffness(&self, p: f64) -> f64 {
        oil_stiffness(&self.fluid, self.air, p)
    }

    /// What the chambers offer a neighbour that carries their pressures over a
    /// co-simulation step (docs/cosim.md): the flows leaving them at constant pressure
    /// (piston displacement and leakage), their volumes and moduli, so that
    /// dP_i/dt = beta_i/V_i (Q_i - Q_displaced,i) as in (4.1).
    pub fn chamber_port(&self, x: &[f64]) -> [f64; 6] {
        let a = &self.actuator;
        let p = [x[P1], x[P2]];
        let (q12, qf) = a.leakage(p, self.tank);
        let vol = a.chamber_volumes(x[Y]);
        let av = a.area * x[V];
        [
            q12 + qf[0] + av,
            -q12 + qf[1] - av,
            vol[0],
            vol[1],
            self.stiffness(p[0]),
            self.stiffness(p[1]),
        ]
    }

    /// Flow states' absolute tolerance and scale for flows a co-simulation step carries
    /// (1e-3 L/min, as the manifold's passages).
    pub fn flow_state(name: &str) -> State {
        State::new(name, "m3/s", 1e-3 * LPM, 1e-5)
    }
}

impl Component for ActuatorComponent {
    fn signature(&self) -> &Signature {
        &self.signature
    }

    fn derivatives(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
        let a = &self.actuator;
        let p = [x[P1], x[P2]];
        let dp = a.pressure_derivatives(x[Y], x[V], p, [u[Q1], u[Q2]], self.tank, |p| {
            self.stiffness(p)
        });
        dx[P1..P2 + 1].copy_from_slice(&dp);
        // (4.4) motion
        dx[Y] = x[V];
        dx[V] = a.motion(x[Y], x[V], p, u[F_EXT]).acceleration;
    }

    fn outputs_at(&self, x: &[f64], _u: &[f64], y: &mut [f64]) {
        y[OUT_P1] = x[P1];
        y[OUT_P2] = x[P2];
    }

    fn jacobian(&self, x: &[f64], u: &[f64], jac: &mut Jacobian) {
        let a = &self.actuator;
        let (y, v, p1, p2) = (x[Y], x[V], x[P1], x[P2]);
        *jac.yx(OUT_P1, P1) = 1.0;
        *jac.yx(OUT_P2, P2) = 1.0;
        *jac.fx(Y, V) = 1.0;

        // (4.4): M a = A (P1 - P2) - M g - F_ext + F_stop(y, v) - b v - F_dry(v)
        let m = a.inertial_mass;
        let half = 0.5 * a.stroke;
        let (stop_y, stop_v) = if y > half {
            (
                -END_STOP_STIFFNESS,
                if v > 0.0 { -END_STOP_DAMPING } else { 0.0 },
            )
        } else if y < -half {
            (
                -END_STOP_STIFFNESS,
                if v < 0.0 { -END_STOP_DAMPING } else { 0.0 },
            )
        } else {
            (0.0, 0.0)
        };
        // the Sidhom branch is the one the right-hand side picks (a discrete choice)
        let dry = a.friction.as_ref().map_or(0.0, |fp| {
            let driving = a.area * (p1 - p2) - a.weight_mass * crate::params::GRAVITY - u[F_EXT]
                + a.end_stop_force(y, v);
            dry_friction_slope(fp, v, driving * v > 0.0)
        });
        *jac.fx(V, Y) = stop_y / m;
        *jac.fx(V, V) = (stop_v - a.viscous - dry) / m;
        *jac.fx(V, P1) = a.area / m;
        *jac.fx(V, P2) = -a.area / m;
        *jac.fu(V, F_EXT) = -1.0 / m;

        // (4.1)-(4.2): P_i' = beta(P_i)/V_i(y) N_i, N_i the net inflow
        let floor = crate::actuator::MIN_VOLUME_FRACTION * a.dead_volume;
        let vol = a.chamber_volumes(y);
        let raw = [
            a.dead_volume + a.area * (half + y),
            a.dead_volume + a.area * (half - y),
        ];
        let d_vol = [
            if raw[0] > floor { a.area } else { 0.0 },
            if raw[1] > floor { -a.area } else { 0.0 },
        ];
        let (ki, ke) = (a.internal_leakage, a.external_leakage);
        let q12 = ki * (p1 - p2);
        let net = [
            u[Q1] - q12 - ke * (p1 - self.tank) - a.area * v,
            u[Q2] + q12 - ke * (p2 - self.tank) + a.area * v,
        ];
        let sign_v = [-1.0, 1.0];
        let sign_12 = [-1.0, 1.0];
        for (c, (row, q)) in [(P1, Q1), (P2, Q2)].into_iter().enumerate() {
            let p = x[row];
            let k = self.stiffness(p) / vol[c];
            *jac.fx(row, Y) = -k * net[c] / vol[c] * d_vol[c];
            *jac.fx(row, V) = k * sign_v[c] * a.area;
            *jac.fx(row, P1) = k * sign_12[c] * ki;
            *jac.fx(row, P2) = -k * sign_12[c] * ki;
            *jac.fx(row, row) +=
                oil_stiffness_slope(&self.fluid, self.air, p) / vol[c] * net[c] - k * ke;
            *jac.fu(row, q) = k;
        }
    }
}
