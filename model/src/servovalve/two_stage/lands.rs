//! Flow through the four metering lands of the second stage (thesis section 2.2.3):
//! rounded edges and radial clearance (2.17)-(2.19), Reynolds-dependent discharge
//! coefficient (2.21)-(2.25), Hagen-Poiseuille leakage at overlap with an equivalent
//! length (2.26), C1 transition between the two (2.27)-(2.31), and the axial flow force
//! with the von Mises jet angle (2.33)-(2.34), (2.43).
//!
//! One land is described by its local opening x_si (2.18): positive when the land is
//! open (underlap), negative when the spool overlaps the port.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};

/// Table 2.1: initial overlaps x_s10..x_s40 of the four lands (m). Land 1 meters P->A,
/// land 2 A->T, land 3 B->T, land 4 P->B (2.40); a positive value is an overlap.
pub const LAND_OVERLAPS: [f64; 4] = [7.6e-6, 7.1e-6, 18.7e-6, 25.2e-6];
/// Table 2.1: diameter of the rounded edges d_r (m).
pub const EDGE_DIAMETER: f64 = 18.7e-6;
/// Table 2.1: radial clearance between spool and sleeve e_s (m).
pub const RADIAL_CLEARANCE: f64 = 2.4e-6;
/// Table 2.1: k_t, transition length L_t = k_t d_0 of the overlap leakage (2.30)-(2.31).
pub const TRANSITION_FACTOR: f64 = 10.0;
/// Table 2.1: laminar flow coefficient delta_Re of (2.23).
pub const LAMINAR_FLOW_COEFFICIENT: f64 = 0.151;

/// Turbulent discharge coefficient C_d_inf of (2.23) (not printed in the thesis). The
/// von Mises asymptote of Fig. 2.9 for a sharp-edged slot, pi / (pi + 2).
pub const CD_TURBULENT: f64 = std::f64::consts::PI / (std::f64::consts::PI + 2.0);

/// Geometry and fluid of one spool valve's lands.
#[derive(Debug, Clone)]
pub struct LandModel {
    /// n * w_s, total width of the metering slots of one land (m).
    pub slot_width: f64,
    /// Dynamic viscosity (Pa.s) and density (kg/m3) of the oil.
    pub viscosity: f64,
    pub density: f64,
    /// d_0 of (2.19), k_s of (2.30), k_I of (2.31), L_t = k_t d_0 (m).
    pub d0: f64,
    pub ks: f64,
    pub ki: f64,
    pub lt: f64,
    jet: JetAngle,
}

impl LandModel {
    pub fn new(slot_width: f64, viscosity: f64, density: f64) -> Self {
        let (es, dr, delta) = (RADIAL_CLEARANCE, EDGE_DIAMETER, LAMINAR_FLOW_COEFFICIENT);
        // (2.19) opening at the edge, x_si = 0
        let d0 = ((es + dr).powi(2) + dr * dr).sqrt() - dr;
        // (2.30) inlet/outlet loss length, from the continuity of the flow at x_si = 0
        let ks = es.powi(3) / (48.0 * delta * delta * d0 * d0);
        // (2.31) inertia loss coefficient, from the continuity of dQ/dx_si at x_si = 0
        let ki = TRANSITION_FACTOR
            * (es.powi(3) * dr / (24.0 * delta * delta * d0 * d0 * (d0 + dr)) - d0);
        LandModel {
            slot_width,
            viscosity,
            density,
            d0,
            ks,
            ki,
            lt: TRANSITION_FACTOR * d0,
            jet: JetAngle::new(),
        }
    }

    /// (2.17) opening diameter d_i between the rounded edge and the sleeve edge (m).
    pub fn opening(&self, x: f64) -> f64 {
        let (es, dr) = (RADIAL_CLEARANCE, EDGE_DIAMETER);
        if x >= -dr {
            ((es + dr).powi(2) + (dr + x).powi(2)).sqrt() - dr
        } else {
            es
        }
    }

    /// f_L of (2.28): the equivalent overlap length of the leakage path (m), x < 0.
    pub fn equivalent_overlap(&self, x: f64) -> f64 {
        self.ks - x + self.ki * (-x / self.lt).tanh()
    }

    /// Laminar conductance Q/dP of the land (m3/s/Pa): (2.28) at underlap (the laminar
    /// branch of (2.25)), (2.26) with the equivalent length f_L at overlap. k_s and k_I
    /// make it and its derivative continuous at x = 0 (2.27), (2.29)-(2.31).
    pub fn laminar_conductance(&self, x: f64) -> f64 {
        let (es, delta, mu, w) = (
            RADIAL_CLEARANCE,
            LAMINAR_FLOW_COEFFICIENT,
            self.viscosity,
            self.slot_width,
        );
        if x >= 0.0 {
            // (2.28) first line: Cd = delta_Re sqrt(Re) with Re from (2.21)-(2.22)
            let d = self.opening(x);
            4.0 * delta * delta * w * d * d / mu
        } else {
            // (2.26)/(2.28) second line: Hagen-Poiseuille over the equivalent length
            w * es.powi(3) / (12.0 * mu * self.equivalent_overlap(x))
        }
    }

    /// Turbulent coefficient Q/sqrt(dP) of the land (m3/s/sqrt(Pa)): (2.25) second line,
    /// Cd_inf n w_s d_i sqrt(2/rho). At overlap d_i is the clearance e_s (2.17).
    pub fn turbulent_coefficient(&self, x: f64) -> f64 {
        CD_TURBULENT * self.slot_width * self.opening(x) * (2.0 / self.density).sqrt()
    }

    /// Flow through the land (m3/s) at opening `x` (m) under the drop `dp` (Pa), positive
    /// in the direction of the drop.
    ///
    /// (2.23) gives the discharge coefficient two asymptotes, laminar delta_Re sqrt(Re)
    /// and turbulent Cd_inf; the laminar one yields Q_lam = G dP (2.28), the turbulent one
    /// Q_turb = c sqrt(dP) (2.25). They are joined by Q^-2 = Q_lam^-2 + Q_turb^-2, which
    /// follows the rounded knee of the measured curve of Fig. 2.9 instead of the corner at
    /// Re_t (2.24) and is smooth in x and dP. It is applied on both sides of x = 0 (with
    /// d_i = e_s at overlap), so the C1 junction of (2.27)-(2.31) carries over to the
    /// total flow at every pressure drop, not only where the flow is laminar: at null under
    /// 100 bar the leakage Reynolds number (about 50) exceeds Re_t = (Cd_inf/delta_Re)^2
    /// = 16, so the purely laminar form would overstate it.
    pub fn flow(&self, x: f64, dp: f64) -> f64 {
        let g = self.laminar_conductance(x);
        let c = self.turbulent_coefficient(x);
        g * dp / (1.0 + g * g * dp.abs() / (c * c)).sqrt()
    }

    /// d(opening)/dx.
    fn opening_slope(&self, x: f64) -> f64 {
        let (es, dr) = (RADIAL_CLEARANCE, EDGE_DIAMETER);
        if x >= -dr {
            (dr + x) / ((es + dr).powi(2) + (dr + x).powi(2)).sqrt()
        } else {
            0.0
        }
    }

    /// d(laminar_conductance)/dx.
    fn laminar_conductance_slope(&self, x: f64) -> f64 {
        let (es, delta, mu, w) = (
            RADIAL_CLEARANCE,
            LAMINAR_FLOW_COEFFICIENT,
            self.viscosity,
            self.slot_width,
        );
        if x >= 0.0 {
            8.0 * delta * delta * w * self.opening(x) * self.opening_slope(x) / mu
        } else {
            let t = (-x / self.lt).tanh();
            let d_overlap = -1.0 - self.ki / self.lt * (1.0 - t * t);
            let f = self.equivalent_overlap(x);
            -w * es.powi(3) * d_overlap / (12.0 * mu * f * f)
        }
    }

    /// Derivatives of [`Self::flow`] with respect to the opening and the drop.
    pub fn flow_slopes(&self, x: f64, dp: f64) -> (f64, f64) {
        let g = self.laminar_conductance(x);
        let c = self.turbulent_coefficient(x);
        let (dg, dc) = (
            self.laminar_conductance_slope(x),
            CD_TURBULENT * self.slot_width * self.opening_slope(x) * (2.0 / self.density).sqrt(),
        );
        // Q = g dp D^(-1/2), D = 1 + g^2 |dp| / c^2
        let r = g * g * dp.abs() / (c * c);
        let d32 = (1.0 + r).powf(-1.5);
        let dq_dg = dp * d32;
        let dq_dc = g * dp * r / c * d32;
        (dq_dg * dg + dq_dc * dc, g * d32 * (1.0 + 0.5 * r))
    }

    /// Derivatives of [`Self::flow_force`] with respect to the opening and the flow.
    pub fn flow_force_slopes(&self, x: f64, q: f64) -> (f64, f64) {
        let d = self.opening(x);
        let r = d / RADIAL_CLEARANCE;
        let theta = self.jet.angle(r);
        let d_theta = self.jet.angle_slope(r) / RADIAL_CLEARANCE;
        let k = self.density / self.slot_width;
        // F = k q^2 cos(theta(d)) / d
        let d_f_dd = k * q * q * (-theta.sin() * d_theta / d - theta.cos() / (d * d));
        (
            d_f_dd * self.opening_slope(x),
            2.0 * k * q * theta.cos() / d,
        )
    }

    /// Metering area n w_s d_i of the land (m2), A_si of (2.43).
    pub fn area(&self, x: f64) -> f64 {
        self.slot_width * self.opening(x)
    }

    /// (2.33) axial flow force magnitude rho Q^2 cos(theta) / A (N) of a land passing `q`;
    /// it always tends to close the land, (2.43) gives the signs.
    pub fn flow_force(&self, x: f64, q: f64) -> f64 {
        let d = self.opening(x);
        // (2.34) jet angle from the opening and the radial clearance
        let theta = self.jet.angle(d / RADIAL_CLEARANCE);
        self.density * q * q * theta.cos() / (self.slot_width * d)
    }
}

/// Jet angle theta (rad) against the ratio of opening to radial clearance, (2.34).
///
/// The extracted text of (2.34) is mangled; the form used here is Merritt's (after von
/// Mises' free-streamline solution): x_v/C_r = N(theta)/N(pi/2 - theta) with
/// N(t) = 1 + (pi/2) sin t + cos t ln tan(t/2) (ln tan((pi - t)/2) = -ln tan(t/2) as
/// printed). It gives the two classic limits, 69 deg for a sharp edge without clearance
/// (x_v/C_r -> infinity) and 21 deg when the clearance dominates, 45 deg at x_v = C_r.
/// Tabulated once against ln(x_v/C_r) and read by cubic Hermite interpolation.
#[derive(Debug, Clone)]
struct JetAngle {
    table: Vec<f64>,
}

const JET_STEP: f64 = 0.1;
const JET_POINTS: usize = 121;

fn jet_n(t: f64) -> f64 {
    1.0 + FRAC_PI_2 * t.sin() + t.cos() * (0.5 * t).tan().ln()
}

/// Jet angle of a sharp edge without clearance (x_v/C_r -> infinity): pi/2 - t0 with
/// N(t0) = 0, the von Mises 69 deg.
fn sharp_edge_angle() -> f64 {
    let (mut lo, mut hi) = (0.2f64, FRAC_PI_4);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if jet_n(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    FRAC_PI_2 - 0.5 * (lo + hi)
}

impl JetAngle {
    fn new() -> Self {
        let limit = sharp_edge_angle();
        let ratio = |t: f64| (jet_n(t) / jet_n(FRAC_PI_2 - t)).ln();
        let table = (0..JET_POINTS)
            .map(|k| {
                let u = k as f64 * JET_STEP;
                let (mut a, mut b) = (FRAC_PI_4, limit - 1e-15);
                for _ in 0..100 {
                    let m = 0.5 * (a + b);
                    if ratio(m) < u {
                        a = m;
                    } else {
                        b = m;
                    }
                }
                0.5 * (a + b)
            })
            .collect();
        JetAngle { table }
    }

    /// The Hermite segment of x_v/C_r = r: its index k, the position s in it and the
    /// end slopes; None beyond the table, where the angle is held.
    fn segment(&self, r: f64) -> Option<(usize, f64, f64, f64)> {
        let u = r.max(1.0).ln() / JET_STEP;
        let n = JET_POINTS - 1;
        if u >= n as f64 {
            return None;
        }
        let k = (u.floor() as usize).min(n - 1);
        let t = &self.table;
        let slope = |j: usize| {
            let (a, b) = (j.saturating_sub(1), (j + 1).min(n));
            (t[b] - t[a]) / (b - a) as f64
        };
        Some((k, u - k as f64, slope(k), slope(k + 1)))
    }

    /// Jet angle for x_v/C_r = r (r >= 1 here: the opening never falls below e_s).
    fn angle(&self, r: f64) -> f64 {
        let t = &self.table;
        let Some((k, s, m0, m1)) = self.segment(r) else {
            return t[JET_POINTS - 1];
        };
        let (s2, s3) = (s * s, s * s * s);
        (2.0 * s3 - 3.0 * s2 + 1.0) * t[k]
            + (s3 - 2.0 * s2 + s) * m0
            + (-2.0 * s3 + 3.0 * s2) * t[k + 1]
            + (s3 - s2) * m1
    }

    /// d(angle)/dr: the derivative of the Hermite cubic, zero where the angle is held.
    fn angle_slope(&self, r: f64) -> f64 {
        let t = &self.table;
        let Some((k, s, m0, m1)) = self.segment(r).filter(|_| r >= 1.0) else {
            return 0.0;
        };
        let s2 = s * s;
        let d_ds = (6.0 * s2 - 6.0 * s) * t[k]
            + (3.0 * s2 - 4.0 * s + 1.0) * m0
            + (-6.0 * s2 + 6.0 * s) * t[k + 1]
            + (3.0 * s2 - 2.0 * s) * m1;
        // u = ln(r) / step
        d_ds / (JET_STEP * r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{BAR, LPM};

    fn lands() -> LandModel {
        LandModel::new(14e-3, 0.04, 862.0)
    }

    #[test]
    fn transition_constants_follow_table_2_1() {
        let l = lands();
        // (2.19) with Table 2.1: sqrt(21.1^2 + 18.7^2) - 18.7 um
        assert!((l.d0 * 1e6 - 9.494).abs() < 1e-3, "d0 = {} um", l.d0 * 1e6);
        assert!(l.ks > 0.0 && l.ki < 0.0 && l.ki > -l.lt);
        // the equivalent overlap length stays positive and grows with the overlap
        let mut prev = 0.0;
        for k in 1..2000 {
            let f = l.equivalent_overlap(-(k as f64) * 1e-7);
            assert!(f > prev, "f_L must grow with the overlap");
            prev = f;
        }
    }

    /// Flow and d(flow)/dx continuous across x_si = 0 for every land of Table 2.1, at
    /// small (laminar) and supply-sized (turbulent) pressure drops, on a fine grid.
    #[test]
    fn flow_and_slope_are_continuous_across_the_overlap_transition() {
        let l = lands();
        let h = 1e-10; // 0.1 nm grid
        for (k, x0) in LAND_OVERLAPS.iter().enumerate() {
            for dp in [0.5 * BAR, 35.0 * BAR, 106.0 * BAR, 213.0 * BAR] {
                // each land's own opening as the spool crosses its edge, on a grid of
                // spool positions around x_s = x_si0 (lands 1, 3) or -x_si0 (2, 4)
                let open = |xs: f64| if k % 2 == 0 { xs - x0 } else { -xs - x0 };
                let edge = if k % 2 == 0 { *x0 } else { -*x0 };
                let q = |xs: f64| l.flow(open(xs), dp);
                let g = |xs: f64| l.laminar_conductance(open(xs)) * dp;
                for f in [&q as &dyn Fn(f64) -> f64, &g] {
                    let scale = f(edge).abs();
                    // value: the jump over one grid step is of the order of the slope
                    let slope = |xs: f64| (f(xs + h) - f(xs - h)) / (2.0 * h);
                    let s_left = slope(edge - 2.0 * h);
                    let s_right = slope(edge + 2.0 * h);
                    let jump = (f(edge + 0.5 * h) - f(edge - 0.5 * h)).abs();
                    assert!(
                        jump <= 2.0 * h * s_left.abs().max(s_right.abs()) + 1e-12 * scale,
                        "land {}: flow jumps by {jump:e} at the edge ({} bar)",
                        k + 1,
                        dp / BAR
                    );
                    let rel = (s_left - s_right).abs() / s_left.abs().max(s_right.abs());
                    assert!(
                        rel < 1e-3,
                        "land {}: slope {s_left:e} | {s_right:e} at the edge ({} bar)",
                        k + 1,
                        dp / BAR
                    );
                    // the slope varies smoothly around the edge on a 1 nm grid
                    for j in -50..50 {
                        let xa = edge + j as f64 * 1e-9;
                        let (sa, sb) = (slope(xa), slope(xa + 1e-9));
                        assert!(
                            (sa - sb).abs() <= 0.05 * sa.abs().max(sb.abs()),
                            "land {}: slope kink near x = {xa:e}",
                            k + 1
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn a_broken_k_i_would_be_caught() {
        // the continuity test above is not vacuous: with k_I off by 10 % the slope of the
        // laminar conductance jumps at the edge
        let mut l = lands();
        l.ki *= 1.1;
        let h = 1e-10;
        let g = |x: f64| l.laminar_conductance(x);
        let (sl, sr) = (
            (g(-h) - g(-3.0 * h)) / (2.0 * h),
            (g(3.0 * h) - g(h)) / (2.0 * h),
        );
        assert!((sl - sr).abs() / sr.abs() > 0.01, "{sl} {sr}");
    }

    #[test]
    fn turbulent_far_from_the_edge_laminar_at_small_drops() {
        let l = lands();
        let x = 0.4e-3;
        let q = l.flow(x, 35.0 * BAR);
        let qt = l.turbulent_coefficient(x) * (35.0 * BAR).sqrt();
        assert!((q / qt - 1.0).abs() < 1e-3, "{} L/min", q / LPM);
        let dp = 1.0; // Pa
        assert!((l.flow(-20e-6, dp) / (l.laminar_conductance(-20e-6) * dp) - 1.0).abs() < 1e-6);
        assert_eq!(l.flow(1e-4, -3e6), -l.flow(1e-4, 3e6));
    }

    #[test]
    fn jet_angle_limits_and_flow_force() {
        let j = JetAngle::new();
        let deg = |r: f64| j.angle(r).to_degrees();
        assert!((deg(1.0) - 45.0).abs() < 1e-6);
        let limit = sharp_edge_angle().to_degrees();
        assert!((limit - 69.0).abs() < 0.3, "{limit}");
        assert!(deg(1e6) > 68.0 && deg(1e6) <= limit + 1e-9);
        let mut prev = 0.0;
        for k in 0..400 {
            let a = deg(1.0 + k as f64 * 0.5);
            assert!(a >= prev);
            prev = a;
        }
        // 5 L/min through a 0.1 mm opening: a few newtons, as the CFD of Fig. 2.14(b)
        let l = lands();
        let f = l.flow_force(0.1e-3, 5.0 * LPM);
        assert!(f > 0.3 && f < 3.0, "{f} N");
    }
}
