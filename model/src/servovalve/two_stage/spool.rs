//! Second stage: the spool (2.41)-(2.43), its four metering lands (2.18), (2.40) and the
//! static characteristics measured on it in section 2.2.3 (blocked ports, rated flow).

use super::lands::LAND_OVERLAPS;
use super::TwoStageServovalve;
use crate::servovalve::PortPressures;

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

/// The four land flows Q_s1..Q_s4 of (2.40) (m3/s) and their openings x_si (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LandFlows {
    pub q: [f64; 4],
    pub x: [f64; 4],
}

impl TwoStageServovalve {
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
