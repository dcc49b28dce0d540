//! Reduced MOOG D765 model: the static flow law (II.2) on the four spool lands, an
//! optional second-order spool response with a rate limit, and the laminar leakage of
//! the lands at null.
//!
//! The spool position is carried as a fraction of the rated opening (1 = rated command).
//! (II.2) gives a land the flow Qn/un * u * sqrt(|dp|/dPn). The catalogue's rated flow,
//! 19 L/min, holds for a 70 bar drop over the valve, i.e. two lands in series, so a
//! single land meters Qn at dPn/2 = 35 bar; the thesis's (II.2) puts the whole 70 bar on
//! one land, a sqrt(2) smaller gain suited to its control design. We measured both in
//! the section 4.4 step test: the catalogue reading gives 95 % times of 0.051/0.024/0.051 s
//! in modes 1/2/3, faster than the bench's 0.058/0.028/0.055 s, as the thesis's own
//! simulation was ("the system responds faster in simulation than in experiment",
//! blamed on torque-motor hysteresis); the (II.2) reading gives 0.072/0.035/0.072 s,
//! slower than the bench. The physical (catalogue) reading is the default.
//!
//! The identified defaults of this model (null leakage and width, spool dynamics) are
//! declared with the valve's parameters in `params::valve`, where the parameter tree's
//! defaults are built from them.

use super::port::{P_A, P_B, P_S, P_T, Q_A, Q_B, Q_S, U, X_S};
use super::{signed_sqrt, PortFlows, PortPressures, Servovalve};
use crate::fluid::signed_sqrt_slope;
use crate::jacobian::Jacobian;
use crate::params::{ValveParams, BAR};

/// Spool travel at rated command (m). The thesis prints no spool geometry; a land of a
/// D765-class spool (about 8 mm diameter, two-thirds of its circumference ported) passes
/// 19 L/min at 35 bar with about 0.4 mm of opening, so the rated stroke is taken as that.
pub const RATED_SPOOL_STROKE: f64 = 0.4e-3;

/// Land pressure drop below which the orifice flow turns laminar (Pa). Small enough to
/// change the flow by less than 0.01 % at 35 bar, large enough to keep the Jacobian of a
/// nearly balanced land finite.
pub const LAND_LAMINAR_TRANSITION: f64 = 0.5 * BAR;

/// Spool travel (fraction of rated) over which a land's edge opens from zero to its
/// full metering gain. It stands for the rounded edges of Table 2.1 (d_r = 18.7 um, about
/// 5 % of the 0.4 mm stroke, of which the first tenth acts): it gives the turbulent flow a
/// continuous derivative at the edge, so only the laminar leakage sets the null.
pub const EDGE_ROUNDING: f64 = 0.005;

#[derive(Debug, Clone)]
pub struct ReducedServovalve {
    p: ValveParams,
    dynamics: bool,
    /// Land leakage conductance at null, already scaled by temperature; 0 when off.
    null_leakage: f64,
    /// Metering coefficient of one land per unit of normalised opening (m3/s/sqrt(Pa)).
    land_coefficient: f64,
}

impl ReducedServovalve {
    /// `laminar_scale` multiplies laminar conductances (mu_ref/mu at the oil temperature).
    pub fn new(p: &ValveParams, dynamics: bool, leakage: bool, laminar_scale: f64) -> Self {
        ReducedServovalve {
            p: *p,
            dynamics,
            null_leakage: if leakage {
                p.null_leakage * laminar_scale
            } else {
                0.0
            },
            land_coefficient: p.rated_flow / (0.5 * p.rated_pressure_drop).sqrt(),
        }
    }

    /// Spool position demanded by the command, as a fraction of rated.
    fn demanded_opening(&self, command: f64) -> f64 {
        ((command - self.p.null_bias) / self.p.rated_command).clamp(-1.0, 1.0)
    }

    fn opening(&self, command: f64, x: &[f64]) -> f64 {
        if self.dynamics {
            x[0]
        } else {
            self.demanded_opening(command)
        }
    }

    /// Flow through one land of opening `x` (fraction of rated) under drop `dp`.
    fn land_flow(&self, x: f64, dp: f64) -> f64 {
        // (II.2) turbulent metering flow through the open edge
        let metered =
            self.land_coefficient * edge_opening(x) * signed_sqrt(dp, LAND_LAMINAR_TRANSITION);
        // laminar leakage through the radial clearance; it moves from the closing land to
        // the opening one over NULL_WIDTH, as a logistic so both stay positive
        // once the edge opens, the metering flow takes the clearance's place
        let fade = (-edge_opening(x) / self.p.null_width).exp();
        let leak = 2.0 * self.null_leakage * logistic(2.0 * x / self.p.null_width) * fade * dp;
        metered + leak
    }
}

impl ReducedServovalve {
    /// Derivatives of [`Self::land_flow`] with respect to the opening and the drop.
    fn land_flow_slopes(&self, x: f64, dp: f64) -> (f64, f64) {
        let t = LAND_LAMINAR_TRANSITION;
        let (e, de) = (edge_opening(x), edge_opening_slope(x));
        let w = self.p.null_width;
        let fade = (-e / w).exp();
        let sig = logistic(2.0 * x / w);
        let d_sig = sig * (1.0 - sig) * 2.0 / w;
        let leak = 2.0 * self.null_leakage;
        let d_x = self.land_coefficient * de * signed_sqrt(dp, t)
            + leak * dp * fade * (d_sig - sig * de / w);
        let d_dp = self.land_coefficient * e * signed_sqrt_slope(dp, t) + leak * sig * fade;
        (d_x, d_dp)
    }

    /// d(opening)/d(command) of the static opening: the branch the clamp takes.
    fn demanded_opening_slope(&self, command: f64) -> f64 {
        let s = (command - self.p.null_bias) / self.p.rated_command;
        if s.abs() < 1.0 {
            1.0 / self.p.rated_command
        } else {
            0.0
        }
    }
}

fn edge_opening_slope(x: f64) -> f64 {
    if x <= 0.0 {
        0.0
    } else if x < EDGE_ROUNDING {
        x / EDGE_ROUNDING
    } else {
        1.0
    }
}

/// C1 ramp: zero for a closed land, quadratic over the rounded edge, then linear.
fn edge_opening(x: f64) -> f64 {
    if x <= 0.0 {
        0.0
    } else if x < EDGE_ROUNDING {
        x * x / (2.0 * EDGE_ROUNDING)
    } else {
        x - 0.5 * EDGE_ROUNDING
    }
}

fn logistic(z: f64) -> f64 {
    1.0 / (1.0 + (-z).exp())
}

impl Servovalve for ReducedServovalve {
    fn n_states(&self) -> usize {
        if self.dynamics {
            2
        } else {
            0
        }
    }

    fn initial_state(&self, command: f64, x: &mut [f64]) {
        if self.dynamics {
            x[0] = self.demanded_opening(command);
            x[1] = 0.0;
        }
    }

    fn absolute_tolerances(&self, atol: &mut [f64]) {
        if self.dynamics {
            atol[0] = 1e-7; // 0.04 nm of spool travel
            atol[1] = 1e-4;
        }
    }

    fn derivatives(&self, command: f64, x: &[f64], dx: &mut [f64]) {
        if !self.dynamics {
            return;
        }
        let r = self.p.max_spool_rate;
        let wn = self.p.natural_frequency;
        // spool velocity saturates at the pilot stage's maximum flow
        dx[0] = r * (x[1] / r).tanh();
        dx[1] =
            wn * wn * (self.demanded_opening(command) - x[0]) - 2.0 * self.p.damping * wn * x[1];
    }

    fn spool_position(&self, command: f64, x: &[f64]) -> f64 {
        self.opening(command, x) * RATED_SPOOL_STROKE
    }

    fn state_names(&self) -> &'static [&'static str] {
        if self.dynamics {
            &["spool", "spool_rate"]
        } else {
            &[]
        }
    }

    fn state_units(&self) -> &'static [&'static str] {
        if self.dynamics {
            &["1", "1/s"]
        } else {
            &[]
        }
    }

    fn jacobian(&self, command: f64, x: &[f64], p: &PortPressures, jac: &mut Jacobian) {
        let s = self.opening(command, x);
        // where the opening comes from: the spool state, or the command directly
        let d_open = |jac: &mut Jacobian, out: usize, d: f64| {
            if self.dynamics {
                *jac.yx(out, 0) += d;
            } else {
                *jac.yu(out, U) += d * self.demanded_opening_slope(command);
            }
        };
        let (pa_x, pa_dp) = self.land_flow_slopes(s, p.supply - p.a);
        let (at_x, at_dp) = self.land_flow_slopes(-s, p.a - p.tank);
        let (pb_x, pb_dp) = self.land_flow_slopes(-s, p.supply - p.b);
        let (bt_x, bt_dp) = self.land_flow_slopes(s, p.b - p.tank);
        // Q_A = q(s, Ps - Pa) - q(-s, Pa - Pt)
        d_open(jac, Q_A, pa_x + at_x);
        *jac.yu(Q_A, P_S) = pa_dp;
        *jac.yu(Q_A, P_A) = -pa_dp - at_dp;
        *jac.yu(Q_A, P_T) = at_dp;
        // Q_B = q(-s, Ps - Pb) - q(s, Pb - Pt)
        d_open(jac, Q_B, -pb_x - bt_x);
        *jac.yu(Q_B, P_S) = pb_dp;
        *jac.yu(Q_B, P_B) = -pb_dp - bt_dp;
        *jac.yu(Q_B, P_T) = bt_dp;
        // Q_P = q(s, Ps - Pa) + q(-s, Ps - Pb)
        d_open(jac, Q_S, pa_x - pb_x);
        *jac.yu(Q_S, P_S) = pa_dp + pb_dp;
        *jac.yu(Q_S, P_A) = -pa_dp;
        *jac.yu(Q_S, P_B) = -pb_dp;
        d_open(jac, X_S, RATED_SPOOL_STROKE);
        if self.dynamics {
            let r = self.p.max_spool_rate;
            let wn = self.p.natural_frequency;
            let t = (x[1] / r).tanh();
            *jac.fx(0, 1) = 1.0 - t * t;
            *jac.fx(1, 0) = -wn * wn;
            *jac.fx(1, 1) = -2.0 * self.p.damping * wn;
            *jac.fu(1, U) = wn * wn * self.demanded_opening_slope(command);
        }
    }

    fn flows(&self, command: f64, x: &[f64], p: &PortPressures) -> PortFlows {
        let s = self.opening(command, x);
        PortFlows {
            a: self.land_flow(s, p.supply - p.a) - self.land_flow(-s, p.a - p.tank),
            b: self.land_flow(-s, p.supply - p.b) - self.land_flow(s, p.b - p.tank),
            // (II.2) the two lands that meter from P
            supply: self.land_flow(s, p.supply - p.a) + self.land_flow(-s, p.supply - p.b),
        }
    }
}

/// -3 dB frequency (Hz) of the spool position for a sine command of `amplitude` (fraction
/// of rated), ports blocked, from the first harmonic after four settling cycles.
pub fn spool_bandwidth(v: &ReducedServovalve, amplitude: f64) -> f64 {
    let gain_at = |f: f64| {
        let dt = 1.0 / (f * 400.0);
        let mut x = [0.0, 0.0];
        let (mut s, mut c) = (0.0, 0.0);
        let cycles = 6.0;
        let n = (cycles * 400.0) as usize;
        for k in 0..n {
            // classic RK4 at 400 points a cycle: the two spool states are not stiff
            let t = k as f64 * dt;
            let d = |t: f64, x: &[f64; 2]| {
                let mut dx = [0.0; 2];
                let u = 10.0 * amplitude * (2.0 * std::f64::consts::PI * f * t).sin();
                v.derivatives(u, x, &mut dx);
                dx
            };
            let k1 = d(t, &x);
            let k2 = d(
                t + dt / 2.0,
                &[x[0] + dt / 2.0 * k1[0], x[1] + dt / 2.0 * k1[1]],
            );
            let k3 = d(
                t + dt / 2.0,
                &[x[0] + dt / 2.0 * k2[0], x[1] + dt / 2.0 * k2[1]],
            );
            let k4 = d(t + dt, &[x[0] + dt * k3[0], x[1] + dt * k3[1]]);
            for i in 0..2 {
                x[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
            if k as f64 >= (cycles - 2.0) * 400.0 {
                let w = 2.0 * std::f64::consts::PI * f * (t + dt);
                s += x[0] * w.sin();
                c += x[0] * w.cos();
            }
        }
        let m = 2.0 / (2.0 * 400.0);
        (s * m).hypot(c * m) / amplitude
    };
    let (mut lo, mut hi) = (20.0f64, 2000.0f64);
    for _ in 0..30 {
        let mid = (lo * hi).sqrt();
        if gain_at(mid) > 0.5f64.sqrt() {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::LPM;

    fn valve(dynamics: bool) -> ReducedServovalve {
        ReducedServovalve::new(&ValveParams::default(), dynamics, true, 1.0)
    }

    /// Pressure of a blocked port A at spool opening s, by bisection on the flow balance.
    fn blocked_port_pressure(v: &ReducedServovalve, s: f64, ps: f64, pt: f64) -> f64 {
        let (mut lo, mut hi) = (pt, ps);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            let q = v.land_flow(s, ps - mid) - v.land_flow(-s, mid - pt);
            if q > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    #[test]
    fn rated_flow_at_rated_command_and_drop() {
        // (II.2): Qn through one land at un and dPn/2 (two lands in series take dPn)
        let v = valve(false);
        let p = PortPressures {
            supply: 37e5,
            tank: 0.0,
            a: 2e5,
            b: 0.0,
        };
        let q = v.flows(10.0, &[], &p).a;
        assert!((q / (19.0 * LPM) - 1.0).abs() < 0.01, "{} L/min", q / LPM);
    }

    #[test]
    fn blocked_ports_pressure_gain_and_leakage_peak_at_null() {
        let v = valve(false);
        let (ps, pt) = (215e5, 2e5);
        let du = 0.01; // V
        let gain = |u: f64| {
            let pa = |u: f64| blocked_port_pressure(&v, u / 10.0, ps, pt);
            // PA - PB with PB(u) = PA(-u) by symmetry
            ((pa(u + du) - pa(-u - du)) - (pa(u - du) - pa(-u + du))) / (2.0 * du)
        };
        let g = gain(0.0) / BAR;
        assert!(g > 600.0 && g < 2500.0, "pressure gain at null {g} bar/V");
        let leak = |u: f64| {
            let s = u / 10.0;
            let pa = blocked_port_pressure(&v, s, ps, pt);
            let pb = blocked_port_pressure(&v, -s, ps, pt);
            v.land_flow(s, ps - pa) + v.land_flow(-s, ps - pb)
        };
        let q0 = leak(0.0) / LPM;
        assert!((q0 - 1.7).abs() < 0.05, "null leakage {q0} L/min");
        assert!(
            leak(0.3) < leak(0.0) && leak(-0.3) < leak(0.0),
            "leakage peaks at null"
        );
    }

    #[test]
    fn bandwidths_match_the_manufacturer() {
        let v = valve(true);
        let f40 = spool_bandwidth(&v, 0.4);
        let f90 = spool_bandwidth(&v, 0.9);
        assert!((f40 / 310.0 - 1.0).abs() < 0.1, "-3 dB at 40 %: {f40} Hz");
        assert!((f90 / 160.0 - 1.0).abs() < 0.1, "-3 dB at 90 %: {f90} Hz");
    }
}
