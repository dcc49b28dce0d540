//! The state equations of the whole valve (electronics, coils, pilot stage, armature,
//! spool) and its `Servovalve` implementation.

use super::electronics::{saturate, unsaturate};
use super::*;
use crate::servovalve::{PortFlows, PortPressures, Servovalve};

impl TwoStageServovalve {
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

    fn state_names(&self) -> &'static [&'static str] {
        &["i", "theta", "omega", "P_L", "P_R", "x_s", "v_s"]
    }

    fn state_units(&self) -> &'static [&'static str] {
        &["A", "rad", "rad/s", "Pa", "Pa", "m", "m/s"]
    }

    fn jacobian(
        &self,
        command: f64,
        x: &[f64],
        p: &PortPressures,
        jac: &mut crate::jacobian::Jacobian,
    ) {
        super::jacobian::exact(self, command, x, p, jac)
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
