#!/usr/bin/env python3
"""The independent bench simulator ("the peer"): the INSA Lyon bench under 1 kHz sampled
proportional control, solved by scipy's solve_ivp. Physics in peer_model.py (from the
thesis, not from model/); this file holds the experiments, the sampled loop and the CLI.

    python tools/peer/bench_peer.py --scenario moves --duration 10 --mode 3 --rtol 1e-6 \
        [--kp 1169] [--variant FILE.json] [--drive FILE.csv] [--csv OUT.csv] [--json]

--csv writes the 1 kHz samples `time,y_ref,y,v,P1,P2,u1,u2` (s, m, m/s, Pa abs, V): y,
P1, P2 as the sensors deliver them (after a variant's lags and delay), v the true
velocity, u1/u2 the commands applied over the following period.
--json prints {"simulated_seconds", "cpu_seconds", "steps", "rhs_evaluations",
"jacobian_evaluations", "y_final", "rtol", "method"}; cpu_seconds is process time around
the integration loop only.
"""

import argparse
import json
import math
import os
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from peer_model import Bench  # noqa: E402

PERIOD = 1e-3  # dSPACE DS1104 sampling, section 4.4
KP = 1169.0  # V/m, (4.22)
COMMAND_LIMIT = 10.0  # V, the valves' rated input; Fig. 4.8 shows the commands saturate
# Moves as `hbench simulate --scenario moves` defines them (model/src/control/
# trajectory.rs, Trajectory::thesis): -10 mm -> +10 mm at 1 s, back at 2 s, 0.2 s each,
# repeated every 2 s; 7th-order s(tau) = 35 tau^4 - 84 tau^5 + 70 tau^6 - 20 tau^7.
MOVE_LOW, MOVE_HIGH = -10e-3, 10e-3
MOVE_FIRST, MOVE_DURATION, MOVE_HALF_PERIOD = 1.0, 0.2, 1.0
# Steps of Fig. 4.8 as `hbench simulate --scenario steps` (scenario.rs): -10 mm to +10 mm
# at 0.05 s and back at 0.35 s.
STEP_TIMES = (0.05, 0.35)
# Method: Radau. Each 1 ms period is a fresh solve_ivp call (the command steps), so a
# multistep BDF restarts at order 1 every period, while Radau is order 5 from its first
# step. On the 10 s moves at rtol 1e-6 (tools/peer/README.md, measured): Radau 15.1 s CPU,
# 0.002 um from the rtol 1e-9 run; BDF 11.8 s, 0.11 um; at equal accuracy Radau is the
# faster (rtol 1e-4: 9.3 s, 0.023 um; BDF needs rtol 1e-9, 44 s, for 0.006 um).
DEFAULT_METHOD = "Radau"


def move_reference(t):
    """y_ref of the repeating thesis cycle."""
    if t < MOVE_FIRST:
        return MOVE_LOW
    tc = (t - MOVE_FIRST) % (2 * MOVE_HALF_PERIOD)
    rising = tc < MOVE_HALF_PERIOD
    tau = min((tc if rising else tc - MOVE_HALF_PERIOD) / MOVE_DURATION, 1.0)
    s = tau**4 * (35 + tau * (-84 + tau * (70 - 20 * tau)))
    a, b = (MOVE_LOW, MOVE_HIGH) if rising else (MOVE_HIGH, MOVE_LOW)
    return a + (b - a) * s


def step_reference(t):
    n = sum(1 for ts in STEP_TIMES if t >= ts)
    return MOVE_HIGH if n % 2 == 1 else MOVE_LOW


def read_drive(path):
    """A drive CSV: `time` then `y_ref` (closed loop) or `u1,u2` (open loop), fixed period."""
    with open(path) as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    cols = {name: data[:, i] for i, name in enumerate(header)}
    if "time" not in cols or not ({"y_ref"} <= cols.keys() or {"u1", "u2"} <= cols.keys()):
        raise ValueError(f"{path}: need columns time and y_ref, or time, u1 and u2; got {header}")
    t = cols["time"]
    dt = np.diff(t)
    if len(t) < 2 or not np.all(np.isfinite(data)) or np.ptp(dt) > 1e-9 * max(1.0, t[-1]):
        raise ValueError(f"{path}: time must be finite and evenly spaced")
    return cols, float(dt[0])


class Experiment:
    """What drives the bench: a reference under proportional control or open-loop
    commands, sample by sample."""

    def __init__(self, args, bench):
        self.kp = args.kp
        self.mode = bench.mode
        if args.drive:
            cols, self.period = read_drive(args.drive)
            self.n = len(cols["time"])
            self.ref = cols.get("y_ref")
            self.u = None if self.ref is not None else (cols["u1"], cols["u2"])
            self.y0 = self.ref[0] if self.ref is not None else args.y0
        else:
            self.period = PERIOD
            self.n = int(round(args.duration / PERIOD))
            f = {"moves": move_reference, "steps": step_reference}[args.scenario]
            self.ref = np.array([f(k * PERIOD) for k in range(self.n)])
            self.u = None
            self.y0 = self.ref[0]

    def closed(self):
        return self.u is None

    def commands(self, k, y):
        """(y_ref, u1, u2) at sample k from the sensed position; u2 = -u1 (4.22)."""
        if self.u is not None:
            return math.nan, self.u[0][k], self.u[1][k]
        u1 = min(max(self.kp * (self.ref[k] - y), -COMMAND_LIMIT), COMMAND_LIMIT)
        return self.ref[k], u1, -u1


def initial_state(bench, exp):
    """Closed loop: at rest under the loop (y, P1, P2 with v = 0, forces balanced).
    Open loop: at the given y and v = 0 with each chamber's flows balanced (P1, P2); a
    force left over starts the piston moving, as on the bench when the drive starts."""
    mid = 0.5 * (bench.p["supply_pressure"] + bench.p["tank_pressure"])
    closed = exp.closed()
    scale = np.array([1e-3, 1e7, 1e7]) if closed else np.array([1e7, 1e7])

    def state(z):
        z = z * scale
        return bench.state(z[0], z[1], z[2]) if closed else bench.state(exp.y0, z[0], z[1])

    def residual(z):
        x = state(z)
        _, u1, u2 = exp.commands(0, x[0])
        bench.settle_spools(x, u1, u2)
        d = bench.rhs(0.0, x, u1, u2)
        # each chamber's flow balance, read as dP/dt at the oil's own bulk modulus: with
        # entrained air the mixture's modulus falls towards P near vacuum (A.12), and
        # dP/dt there vanishes where the flows do not, a false rest the solver wandered
        # into (air 0.23 %, chirp, seed 2, form error: "not making good progress").
        # Without air the factor is exactly 1.
        r = [
            d[2] * bench.beta / bench.bulk(x[2]) / 1e9,
            d[3] * bench.beta / bench.bulk(x[3]) / 1e9,
        ]
        return [d[1] / 10.0] + r if closed else r

    guess = np.array([exp.y0, mid, mid] if closed else [mid, mid]) / scale
    z, _, ok, msg = fsolve(residual, guess, full_output=True, xtol=1e-12)
    if ok != 1:
        raise RuntimeError(f"no rest state: {msg}")
    x = state(z)
    _, u1, u2 = exp.commands(0, x[0])
    bench.settle_spools(x, u1, u2)
    return x


def run(bench, exp, rtol, method=DEFAULT_METHOD):
    """The sampled loop: at each sample, sense (after the delay), decide, hold, integrate.
    Returns (rows, stats)."""
    x = initial_state(bench, exp)
    # per-state scales (peer_model.Bench.atol) at rtol 1e-6, tightened with rtol
    atol = bench.atol() * (rtol / 1e-6)
    delay = bench.p["sensors.delay"]
    history = []  # (t0, t1, dense solution) of recent periods, for the delay
    keep = int(math.ceil(delay / exp.period)) + 1
    x0 = x.copy()
    rows = np.zeros((exp.n, 8))
    stats = {"steps": 0, "rhs_evaluations": 0, "jacobian_evaluations": 0}
    h = None
    cpu0 = time.process_time()
    for k in range(exp.n):
        t0 = k * exp.period
        xs = x
        if delay > 0:
            ts = t0 - delay
            xs = x0
            for a, b, sol in history:
                if a <= ts <= b:
                    xs = sol(ts)
        y, p1, p2 = bench.sensed(xs)
        yref, u1, u2 = exp.commands(k, y)
        rows[k] = (t0, yref, y, x[1], p1, p2, u1, u2)
        t1 = t0 + exp.period
        sol = solve_ivp(
            bench.rhs, (t0, t1), x, method=method, rtol=rtol, atol=atol,
            args=(u1, u2), first_step=None if h is None else min(h, t1 - t0),
            dense_output=delay > 0,
        )
        if not sol.success:
            raise RuntimeError(f"solver failed at t = {t0:.4f} s: {sol.message}")
        x = sol.y[:, -1]
        if not np.all(np.isfinite(x)):
            raise RuntimeError(f"non-finite state at t = {t1:.4f} s")
        h = sol.t[-1] - sol.t[-2]
        stats["steps"] += len(sol.t) - 1
        stats["rhs_evaluations"] += int(sol.nfev)
        stats["jacobian_evaluations"] += int(sol.njev)
        if delay > 0:
            history.append((t0, t1, sol.sol))
            history = history[-keep:]
    stats["cpu_seconds"] = time.process_time() - cpu0
    stats["simulated_seconds"] = exp.n * exp.period
    stats["y_final"] = float(x[0])
    stats["rtol"] = rtol
    stats["method"] = method
    return rows, stats


def write_csv(path, rows, closed):
    if os.path.exists(path):
        raise FileExistsError(f"{path} exists; not overwriting")
    header = "time,y_ref,y,v,P1,P2,u1,u2"
    r = rows if closed else rows.copy()
    if not closed:
        r[:, 1] = r[:, 2]  # open loop: no reference; y_ref repeats y so the column is finite
    np.savetxt(path, r, delimiter=",", header=header, comments="", fmt="%.10g")


def parse(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", choices=["moves", "steps"], default="moves")
    ap.add_argument("--duration", type=float, default=10.0, help="s (scenarios)")
    ap.add_argument("--mode", type=int, choices=[1, 2, 3], default=3)
    ap.add_argument("--rtol", type=float, default=1e-6)
    ap.add_argument("--kp", type=float, default=KP, help="V/m")
    ap.add_argument("--variant", help="JSON object of parameter values (peer_model.DEFAULTS)")
    ap.add_argument("--drive", help="CSV time,y_ref (closed loop) or time,u1,u2 (open loop)")
    ap.add_argument("--y0", type=float, default=0.0, help="initial position, open-loop drive (m)")
    ap.add_argument("--method", choices=["BDF", "Radau", "LSODA", "RK45"], default=DEFAULT_METHOD)
    ap.add_argument("--csv", help="output CSV (never overwritten)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    if not (a.duration > 0 and math.isfinite(a.duration)):
        ap.error("--duration must be a positive number")
    if not (0 < a.rtol < 1):
        ap.error("--rtol must lie in (0, 1)")
    return a


def main(argv=None):
    args = parse(argv)
    params = {"mode": args.mode}
    if args.variant:
        with open(args.variant) as f:
            v = json.load(f)
        if not isinstance(v, dict):
            sys.exit(f"{args.variant}: expected a JSON object of parameter values")
        params.update(v)
    try:
        bench = Bench(params)
        exp = Experiment(args, bench)
        rows, stats = run(bench, exp, args.rtol, args.method)
        if args.csv:
            write_csv(args.csv, rows, exp.closed())
    except (ValueError, RuntimeError, OSError) as e:
        sys.exit(f"bench_peer: {e}")
    if args.json:
        print(json.dumps(stats))


if __name__ == "__main__":
    main()
