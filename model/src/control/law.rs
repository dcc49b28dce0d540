//! What every control law of chapters 5 and 6 sees and returns.
//!
//! A law is evaluated once per sample (1 kHz on the bench). It receives estimates of the
//! plant state (from the DAO2 differentiator or, for studies, the exact states) and the
//! reference with its derivatives, and returns the two valve commands before saturation.

/// The reference at one sample: position and its first three derivatives (the 7th-order
/// polynomial moves are smooth to jerk), and the pressure reference of the P-Y law.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Reference {
    /// y_d, dy_d/dt, d2y_d/dt2, d3y_d/dt3 (m, m/s, m/s2, m/s3)
    pub y: [f64; 4],
    /// Pressure reference (Pa absolute) and its time derivative (Pa/s).
    pub p: [f64; 2],
}

/// Plant state as the law sees it at a sample.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Estimate {
    pub y: f64,
    pub v: f64,
    /// Acceleration estimate (m/s2): DAO2 gives it; exact-state mode computes it.
    pub a: f64,
    pub p1: f64,
    pub p2: f64,
}

/// Physical data the model-based laws use: the control model (II.1)-(II.2).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ControlModel {
    pub area: f64,
    /// Moving mass including payload as the controller believes it (kg).
    pub mass: f64,
    pub bulk_modulus: f64,
    /// Chamber volume at mid stroke (m3): V_i(y) = v0 +- A y.
    pub v0: f64,
    pub viscous: f64,
    pub supply: f64,
    pub tank: f64,
    /// (II.2) Qn/un and dPn of the flow gain phi_i.
    pub flow_per_volt: f64,
    pub rated_drop: f64,
}

/// A discrete-time control law.
pub trait Law: Send {
    /// Commands u1, u2 (V) before saturation, at time t.
    fn commands(&mut self, t: f64, reference: &Reference, x: &Estimate, period: f64) -> [f64; 2];
    /// Forget the memory (integrators, previous samples).
    fn reset(&mut self) {}
}

/// Smallest land pressure drop (Pa) used in phi_i. Not in the thesis: (II.2) vanishes
/// when a chamber reaches supply (u > 0) or tank (u < 0) pressure and the model-based
/// laws, which divide by phi_i, would not be invertible. 0.1 bar is far below any working
/// drop, so it only bounds the command, which then saturates anyway.
pub const MIN_LAND_DROP: f64 = 1e4;

impl ControlModel {
    /// Chamber volumes V1(y), V2(y) of (II.1).
    pub fn volumes(&self, y: f64) -> (f64, f64) {
        (self.v0 + self.area * y, self.v0 - self.area * y)
    }

    /// Static flow gain phi_i (m3/s/V) of (II.2) for chamber pressure `p` and command
    /// sign `sign` (> 0 fills from the supply, < 0 drains to the tank, 0 the mean of both
    /// as (II.2) gives it).
    pub fn flow_gain(&self, p: f64, sign: f64) -> f64 {
        let land = |drop: f64| (drop.abs().max(MIN_LAND_DROP) / self.rated_drop).sqrt();
        let s = if sign > 0.0 {
            1.0
        } else if sign < 0.0 {
            -1.0
        } else {
            0.0
        };
        self.flow_per_volt * (land(self.supply - p) * (1.0 + s) + land(p - self.tank) * (1.0 - s))
            / 2.0
    }
}

/// The thesis's mode-3 control model (Table 1.1, section 4.4, (II.2) with the
/// catalogue's 35 bar per land), shared by the laws' tests.
#[cfg(test)]
pub(crate) mod fixtures {
    use super::ControlModel;

    pub const MASS: f64 = 5.8;
    pub const AREA: f64 = 9.456e-4;
    pub const BETA: f64 = 1.7e9;
    /// Chamber volume at mid stroke: 14.184 cm3 + A * 0.15 m.
    pub const V0: f64 = 1.56e-4;
    pub const SUPPLY: f64 = 210e5;
    pub const TANK: f64 = 2e5;
    /// 19 L/min at 10 V, in m3/s/V.
    pub const FLOW_PER_VOLT: f64 = 19e-3 / 60.0 / 10.0;
    /// Rated drop per land (70 bar total over two lands).
    pub const RATED_DROP: f64 = 35e5;
    pub const VISCOUS: f64 = 400.0;

    pub fn thesis_model(mass: f64) -> ControlModel {
        ControlModel {
            area: AREA,
            mass,
            bulk_modulus: BETA,
            v0: V0,
            viscous: VISCOUS,
            supply: SUPPLY,
            tank: TANK,
            flow_per_volt: FLOW_PER_VOLT,
            rated_drop: RATED_DROP,
        }
    }
}
