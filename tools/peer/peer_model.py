"""Physics of the independent bench simulator ("the peer").

Written from the thesis (Y. Xu, INSA Lyon 2013; /work/shared/seed), not from model/: a
lumped manifold (Tables 3.3/3.4), static servovalves whose null flow comes from the spool
edge geometry of section 2.2.3, the double-rod actuator (4.1)-(4.4) with viscous friction.
SI units throughout (Pa absolute, m, m3/s, s, N, V).

Parameters are named like the Rust registry's paths where the quantity is the same, so a
variant file reads the same in both simulators; peer-only structure parameters (the
spool-edge geometry, sensor lags) have their own names. An unknown name is an error.
"""

import math

import numpy as np

G = 9.81  # m/s2

# Servovalve spool-edge geometry, Table 2.1 (identified on the bench's D765, um -> m):
# edge overlaps x_si0 (2.18), rounded-edge diameter d_r and radial clearance e_s (2.17),
# laminar flow coefficient delta_Re (2.23).
EDGE_OVERLAP = (7.6e-6, 7.1e-6, 18.7e-6, 25.2e-6)
ROUNDED_EDGE = 18.7e-6
RADIAL_CLEARANCE = 2.4e-6
DELTA_RE = 0.151
# Turbulent discharge coefficient Cd_inf of (2.23): the sharp-edged orifice value of
# Merritt (1967), which the thesis cites for Fig. 2.9; not printed in the thesis.
CD_TURBULENT = 0.61
# Spool stroke at the rated +-10 V (m). Not printed in the thesis; chosen so that the
# ports-closed pressure gain of this static valve near null, (d(P_A - P_B)/du at 0 V, with
# the Table 2.1 edges, supply 215 bar, tank 2 bar), is the measured 850 bar/V of
# Fig. 2.10: the Table 2.1 edges give 19.35 bar/um there, so 850e5 * 10 / 1.935e12 =
# 0.439 mm (checked by tests/python/test_peer.py::test_pressure_gain_near_fig_2_10).
RATED_SPOOL_STROKE = 0.44e-3
RATED_INPUT = 10.0  # V, D765 rated input (Table 1.1)
RATED_EDGES = 2  # metering edges in series in the 4-way rating of Table 1.1
# Oil: ISO VG 46 mineral oil at 40 degC (density 850 kg/m3, kinematic viscosity 46 cSt);
# the thesis gives the laws (appendix A) but not the oil's grade.
DENSITY = 850.0
KINEMATIC_VISCOSITY = 46e-6
ATMOSPHERE = 1.013e5  # Pa
# Gas release below atmospheric pressure, the peer's cavitation (the thesis prints no
# cavitation law): mineral oil in a vented reservoir holds about 9 % of its volume of air
# in solution (Bunsen coefficient 0.08-0.09, Totten, Handbook of Hydraulic Fluid
# Technology); below the atmospheric pressure it was saturated at, the air is taken to
# come out at once, as RELEASED_AIR (1 - P/P_atm)^2 of the oil's volume (at P_atm): zero
# with a zero slope at P_atm, all of it near vacuum. Instant release overstates how fast
# air comes out (seconds on a real bench), which is the side that bounds the pressure.
RELEASED_AIR = 0.09
# Lowest pressure the gas law is evaluated at (Pa): the gas's compliance grows as 1/P^2;
# at 1 kPa the bulk modulus is about 1 kPa, so a pressure that reaches it stays there.
GAS_FLOOR = 1e3
# Smoothing velocity of the dry-friction sign (m/s): tanh(v / V_DRY) is within 1 % of
# sign(v) above 2.6 V_DRY = 0.26 mm/s, far below the 0.22 m/s of a move.
V_DRY = 1e-4
# Reference velocity of a bent viscous law (m/s): the peak speed of the thesis moves,
# 35/16 * 20 mm / 0.2 s = 0.22 m/s, where the bent law and the linear one agree.
V_VISCOUS = 0.22
# Pressure drop of the manifold passages at loss_scale 1: the abacus-based method gives
# 0.39 bar at 30 L/min for passage C1-N2 (Tables 3.1-3.2); a chamber circuit crosses about
# three such passages, so about 1.2 bar at 30 L/min, quadratic in the flow (3.5)-(3.7).
MANIFOLD_LOSS = 3 * 0.39e5 / (30e-3 / 60.0) ** 2  # Pa/(m3/s)^2
# The peer's manifold has no losses unless a variant sets them (lumped, Tables 3.3/3.4).

# Table 3.3: added volume per chamber circuit (m3); Table 3.4: equivalent fluid mass (kg).
ADDED_VOLUME = {1: 1.0041e-4, 2: 1.0041e-4, 3: 7.9754e-5}
FLUID_MASS = {1: 4.70, 2: 2.80, 3: 3.42}

DEFAULTS = {
    "mode": 3,
    "supply_pressure": 210e5,  # pump, Table 1.1
    "tank_pressure": 2e5,  # Table 2.1's test conditions
    "fluid.bulk_modulus": 1.7e9,  # reproduces Table 3.5 (GUIDE)
    "fluid.air_fraction": 0.0,  # appendix A (A.7)-(A.12)
    "fluid.density": DENSITY,
    "actuator.area": 9.456e-4,  # Table 1.1
    "actuator.stroke": 0.3,  # usable stroke, Table 1.1
    "actuator.dead_volume": 14.184e-6,  # each end, Table 1.1
    "actuator.mass": 5.8,  # Table 1.1
    "actuator.payload_mass": 0.0,
    # section 4.4: 1e-4 L/min/bar across the piston
    "actuator.internal_leakage": 1e-4 * 1e-3 / 60.0 / 1e5,
    "actuator.viscous_friction": 400.0,  # section 4.4
    # shape of the viscous law (Bench.friction), c = 0 the linear law of section 4.4; a
    # variant bends it (oil film thinning, c < 0, or thickening, c > 0, with speed)
    "friction.viscous_bend": 0.0,
    "friction.coulomb": 0.0,
    "friction.static_peak": 0.0,
    "friction.stribeck_velocity": 0.01,
    "manifold.volume_scale": 1.0,  # x Table 3.3
    "manifold.inertia_scale": 1.0,  # x Table 3.4
    "manifold.loss_scale": 0.0,  # x MANIFOLD_LOSS
    "sv1.rated_flow": 19e-3 / 60.0,  # 19 L/min at 70 bar (Table 1.1)
    "sv2.rated_flow": 19e-3 / 60.0,
    "sv1.null_bias": 0.0,  # V: the command at which the spool sits at its hydraulic null
    "sv2.null_bias": 0.0,
    "sv1.natural_frequency": 0.0,  # 0: static valve (chapter II's control model)
    "sv2.natural_frequency": 0.0,
    "sv1.damping": 0.7,
    "sv2.damping": 0.7,
    "valve.edge_scale": 1.0,  # multiplier of the Table 2.1 edge geometry (null flow)
    "rated_pressure_drop": 70e5,  # Table 1.1
    "sensors.delay": 0.0,  # s, transport delay of every sample
    "sensors.lvdt_lag": 0.0,  # s, first-order LVDT demodulator lag
    "sensors.pressure_lag": 0.0,  # s, first-order pressure-sensor lag
}


def opening(x):
    """Opening diameter d_i of a rounded spool edge at edge position x (2.17), m."""
    d_r = ROUNDED_EDGE
    if x < -d_r:
        return RADIAL_CLEARANCE
    return math.sqrt((RADIAL_CLEARANCE + d_r) ** 2 + (d_r + x) ** 2) - d_r


def opening_scaled(x, scale):
    """(2.17) with the whole edge geometry (overlap, radius, clearance) scaled."""
    if scale == 1.0:
        return opening(x)
    return scale * opening(x / scale)


class Bench:
    """Right-hand side and sensing of the peer bench for one parameter set."""

    def __init__(self, params=None):
        p = dict(DEFAULTS)
        for k, v in (params or {}).items():
            if k not in DEFAULTS:
                raise ValueError(f"unknown peer parameter '{k}'; known: {sorted(DEFAULTS)}")
            p[k] = v
        self.p = p
        mode = int(p["mode"])
        if mode not in (1, 2, 3):
            raise ValueError(f"mode must be 1, 2 or 3, got {mode}")
        self.mode = mode
        self.area = p["actuator.area"]
        self.beta = p["fluid.bulk_modulus"]
        self.rho = p["fluid.density"]
        self.mu = self.rho * KINEMATIC_VISCOSITY
        self.v_end = p["actuator.dead_volume"] + p["actuator.area"] * p["actuator.stroke"] / 2
        self.v_added = ADDED_VOLUME[mode] * p["manifold.volume_scale"]
        # (4.4) with the Table 3.4 fluid mass moving with the piston (3.16)
        self.weight = (p["actuator.mass"] + p["actuator.payload_mass"]) * G
        self.inertia = (
            p["actuator.mass"] + p["actuator.payload_mass"]
            + FLUID_MASS[mode] * p["manifold.inertia_scale"]
        )
        self.loss = MANIFOLD_LOSS * p["manifold.loss_scale"]
        self.scale = p["valve.edge_scale"]
        # Slit width n*w_s (2.20) of each valve, from its rated flow: Q_n at rated input
        # and the rated TOTAL drop of a 4-way valve (Table 1.1), i.e. two edges in series
        # with half the drop each. (II.2) as printed compares one edge's drop with the
        # whole dP_n, a flow sqrt(2) lower; that version's 95 % step times miss Fig. 4.8
        # (measured: tests/python/test_peer.py, README.md here).
        self.width = []
        for sv in ("sv1", "sv2"):
            d = opening_scaled(RATED_SPOOL_STROKE - EDGE_OVERLAP[0] * self.scale, self.scale)
            q = CD_TURBULENT * d * math.sqrt(2 * p["rated_pressure_drop"] / RATED_EDGES / self.rho)
            self.width.append(p[f"{sv}.rated_flow"] / q)
        self.spool_dyn = [p["sv1.natural_frequency"] > 0, p["sv2.natural_frequency"] > 0]
        # state layout: y, v, P1, P2, [spool1 x, xdot], [spool2 x, xdot], [y_m], [P1_m, P2_m]
        n = 4
        self.i_spool = []
        for dyn in self.spool_dyn:
            self.i_spool.append(n if dyn else None)
            n += 2 if dyn else 0
        self.i_lvdt = n if p["sensors.lvdt_lag"] > 0 else None
        n += 1 if self.i_lvdt is not None else 0
        self.i_press = n if p["sensors.pressure_lag"] > 0 else None
        n += 2 if self.i_press is not None else 0
        self.n = n

    # ---- fluid -------------------------------------------------------------------------
    def bulk(self, pressure):
        """Effective bulk modulus (A.9) of the oil with its free gas, the gas isothermal
        (A.12: beta_g = P): the entrained air a0 (fraction at atmospheric pressure) and,
        below atmospheric pressure, the air that comes out of solution (gas release,
        RELEASED_AIR). Per volume of oil the gas occupies g = (a0 + r(P)) P_atm / P; the
        mixture's compliance is 1/beta + (-dg/dP) / (1 - a0 + g). With the release the
        bulk modulus falls to about P near vacuum, so a chamber's pressure approaches zero
        and never crosses it: the peer's cavitation."""
        a0 = self.p["fluid.air_fraction"]
        if a0 <= 0 and pressure >= ATMOSPHERE:
            return self.beta
        pr = max(pressure, GAS_FLOOR)
        below = max(1.0 - pr / ATMOSPHERE, 0.0)
        released = RELEASED_AIR * below * below
        d_released = 2.0 * RELEASED_AIR * below / ATMOSPHERE  # -dr/dP
        g = (a0 + released) * ATMOSPHERE / pr
        compliance = (g + d_released * ATMOSPHERE) / pr / (1.0 - a0 + g)
        return 1.0 / (1.0 / self.beta + compliance)

    # ---- servovalve ----------------------------------------------------------------------
    def edge_flow(self, valve, x_edge, dp):
        """Flow through one metering edge under drop dp (2.20)-(2.25): the laminar
        asymptote (Cd = delta_Re sqrt(Re)) below the transition Reynolds number, the
        turbulent one above; the smaller of the two is the two-asymptote law of (2.23).
        A manifold loss in series (loss_scale) adds k Q^2 to the turbulent drop."""
        if dp == 0.0:
            return 0.0
        w = self.width[valve]
        d = opening_scaled(x_edge, self.scale)
        adp = abs(dp)
        q_lam = 4 * DELTA_RE**2 / self.mu * w * d * d * adp
        k = CD_TURBULENT * w * d * math.sqrt(2 / self.rho)
        if self.loss > 0:
            q_turb = math.sqrt(adp / (1 / (k * k) + self.loss))
        else:
            q_turb = k * math.sqrt(adp)
        return math.copysign(min(q_lam, q_turb), dp)

    def spool(self, valve, u, x):
        """Spool position (m) of a valve: static (chapter II) or second order."""
        i = self.i_spool[valve]
        if i is not None:
            return x[i] * RATED_SPOOL_STROKE
        bias = self.p[f"sv{valve + 1}.null_bias"]
        return (u - bias) / RATED_INPUT * RATED_SPOOL_STROKE

    def port_flows(self, valve, xs, p_a, p_b):
        """Flows into ports A and B (m3/s) at spool position xs (2.18): edges 1 (P-A) and
        3 (B-T) open with +xs, edges 2 (A-T) and 4 (P-B) with -xs."""
        ps, pt = self.p["supply_pressure"], self.p["tank_pressure"]
        o = [e * self.scale for e in EDGE_OVERLAP]
        q_a = self.edge_flow(valve, xs - o[0], ps - p_a) - self.edge_flow(valve, -xs - o[1], p_a - pt)
        q_b = self.edge_flow(valve, -xs - o[3], ps - p_b) - self.edge_flow(valve, xs - o[2], p_b - pt)
        return q_a, q_b

    def valve_flows(self, x, u1, u2):
        """Flows into chambers 1 and 2 in the working mode (section 1.2): mode 1 SV1
        4-way; mode 2 both valves 4-way in parallel on u1; mode 3 each valve 3-way on
        one chamber (port A), u1 on chamber 1 and u2 on chamber 2."""
        p1, p2 = x[2], x[3]
        x1 = self.spool(0, u1, x)
        if self.mode == 3:
            q1, _ = self.port_flows(0, x1, p1, p2)
            q2, _ = self.port_flows(1, self.spool(1, u2, x), p2, p1)
            return q1, q2
        q1, q2 = self.port_flows(0, x1, p1, p2)
        if self.mode == 2:
            a, b = self.port_flows(1, self.spool(1, u1, x), p1, p2)
            q1, q2 = q1 + a, q2 + b
        return q1, q2

    # ---- actuator --------------------------------------------------------------------------
    def friction(self, v):
        """Viscous friction (section 4.4) plus a dry part in the Tustin form the Sidhom
        model builds on (4.5)-(4.13): Coulomb level with an exponential Stribeck peak."""
        p = self.p
        f = p["actuator.viscous_friction"] * v * self.viscous_shape(abs(v) / V_VISCOUS)
        fc, fs = p["friction.coulomb"], p["friction.static_peak"]
        if fc > 0 or fs > 0:
            peak = max(fs - fc, 0.0) * math.exp(-abs(v) / p["friction.stribeck_velocity"])
            f += (fc + peak) * math.tanh(v / V_DRY)
        return f

    def viscous_shape(self, r):
        """The viscous law's bend at speed r = |v| / V_VISCOUS, as a multiple of the linear
        law: 1 at r = 1 and 1 / (1 + c) at rest for either sign of the bend c. Thickening
        (c > 0): (1 + c r) / (1 + c), a force growing as v^2 at speed. Thinning (c < 0):
        1 / (1 + c - c r), which saturates at b V_VISCOUS / |c|. Both keep the force
        rising with speed and of the sign of v, so friction only dissipates. The thinning
        law was once (1 + c r) / (1 + c) too: its force peaked at r = 1 / (2|c|) and
        reversed beyond 1/|c| (0.86 m/s at c = -0.255), where it fed the motion. The peer's
        advised 2.5 s and 5 s sweeps of seed 1 (c = -0.255) ran away there to 28 m/s and
        700-808 bar, alike under Radau (rtol 1e-6, 1e-8) and BDF (1e-6) (measured,
        docs/gap.md session 22)."""
        c = self.p["friction.viscous_bend"]
        if c >= 0:
            return (1 + c * r) / (1 + c)
        return 1 / (1 + c - c * r)

    def rhs(self, t, x, u1, u2):
        """(4.1), (4.2), (4.4) with the lumped manifold, and the optional lags."""
        y, v, p1, p2 = x[0], x[1], x[2], x[3]
        a = self.area
        q1, q2 = self.valve_flows(x, u1, u2)
        q12 = self.p["actuator.internal_leakage"] * (p1 - p2)
        v1 = self.v_end + a * y + self.v_added
        v2 = self.v_end - a * y + self.v_added
        dx = np.zeros(self.n)
        dx[0] = v
        dx[1] = (a * (p1 - p2) - self.weight - self.friction(v)) / self.inertia
        dx[2] = self.bulk(p1) / v1 * (q1 - q12 - a * v)
        dx[3] = self.bulk(p2) / v2 * (q2 + q12 + a * v)
        for valve, u in ((0, u1), (1, u2)):
            i = self.i_spool[valve]
            if i is not None:
                w = self.p[f"sv{valve + 1}.natural_frequency"]
                z = self.p[f"sv{valve + 1}.damping"]
                target = (u - self.p[f"sv{valve + 1}.null_bias"]) / RATED_INPUT
                dx[i] = x[i + 1]
                dx[i + 1] = w * w * (target - x[i]) - 2 * z * w * x[i + 1]
        if self.i_lvdt is not None:
            dx[self.i_lvdt] = (y - x[self.i_lvdt]) / self.p["sensors.lvdt_lag"]
        if self.i_press is not None:
            tau = self.p["sensors.pressure_lag"]
            dx[self.i_press] = (p1 - x[self.i_press]) / tau
            dx[self.i_press + 1] = (p2 - x[self.i_press + 1]) / tau
        return dx

    def sensed(self, x):
        """(y, P1, P2) as the sensors deliver them (after their lags)."""
        y = x[self.i_lvdt] if self.i_lvdt is not None else x[0]
        if self.i_press is not None:
            return y, x[self.i_press], x[self.i_press + 1]
        return y, x[2], x[3]

    def atol(self):
        """Absolute tolerance per state: a nanometre, a micrometre per second, a pascal."""
        tol = np.full(self.n, 1e-9)
        tol[1] = 1e-6
        tol[2:4] = 1.0
        for i in self.i_spool:
            if i is not None:
                tol[i], tol[i + 1] = 1e-6, 1e-3
        if self.i_press is not None:
            tol[self.i_press : self.i_press + 2] = 1.0
        return tol

    def state(self, y, p1, p2):
        """Full state at rest at y with chamber pressures p1, p2 (lags settled)."""
        x = np.zeros(self.n)
        x[0], x[2], x[3] = y, p1, p2
        if self.i_lvdt is not None:
            x[self.i_lvdt] = y
        if self.i_press is not None:
            x[self.i_press], x[self.i_press + 1] = p1, p2
        return x

    def settle_spools(self, x, u1, u2):
        """Second-order spools at rest at their commanded position (in place)."""
        for valve, u in ((0, u1), (1, u2)):
            i = self.i_spool[valve]
            if i is not None:
                x[i] = (u - self.p[f"sv{valve + 1}.null_bias"]) / RATED_INPUT
                x[i + 1] = 0.0

    def natural_frequencies(self, y):
        """Hydraulic natural frequency (Hz) at position y from (3.8)-(3.11):
        omega^2 = beta A^2 (1/V1 + 1/V2) / M, volumes and mass with the manifold."""
        a = self.area
        v1 = self.v_end + a * y + self.v_added
        v2 = self.v_end - a * y + self.v_added
        return math.sqrt(self.beta * a * a * (1 / v1 + 1 / v2) / self.inertia) / (2 * math.pi)
