"""fmpy.simulate_fmu on every FMU, and the physics each one must show with inputs."""
from __future__ import annotations

import numpy as np
import pytest
from fmpy import simulate_fmu

from conftest import NAMES

LPM = 1.0 / 60000.0  # m3/s per L/min
BAR = 1e5


def signals(rows, names):
    """A structured input array for simulate_fmu: rows of (time, *values)."""
    return np.array(rows, dtype=[("time", float)] + [(n, float) for n in names])


@pytest.mark.parametrize("name", NAMES)
def test_default_experiment_runs(fmus, name):
    u = fmus[name]
    exp = u.md.defaultExperiment
    assert exp is not None and float(exp.stopTime) > float(exp.startTime or 0)
    r = simulate_fmu(str(u.path))
    outputs = u.names("output")
    assert list(r.dtype.names) == ["time"] + outputs
    assert r["time"][0] == pytest.approx(float(exp.startTime or 0))
    assert r["time"][-1] == pytest.approx(float(exp.stopTime))
    assert len(r) > 10
    for n in outputs:
        assert np.all(np.isfinite(r[n])), n


def test_bench_holds_still_at_null_command(fmus):
    r = simulate_fmu(str(fmus["bench"].path))
    assert np.max(np.abs(r["y"])) < 1e-4, "the piston drifts by more than 0.1 mm at u = 0"
    assert np.all((r["P1"] > 0) & (r["P1"] < 250 * BAR))


def test_bench_extends_with_u1_positive_u2_negative(fmus):
    bench = fmus["bench"]
    area = float(bench.var["actuator.area"].start)
    inp = signals([(0.0, 2.0, -2.0, 0.0), (0.05, 2.0, -2.0, 0.0)], ["u1", "u2", "F_ext"])
    r = simulate_fmu(str(bench.path), stop_time=0.05, input=inp, output_interval=1e-3,
                     start_values={"mode": 3})
    t, y, v = r["time"], r["y"], r["v"]
    assert y[-1] - y[0] > 2e-3, f"y moved by {y[-1] - y[0]} m in 50 ms at 2 V"
    assert np.all(np.diff(y[5:]) > 0), "the piston does not keep extending"
    # after the start-up transient the mean velocity is the chamber flow over the area
    late = t >= 0.015
    v_mean = (y[-1] - y[late][0]) / (t[-1] - t[late][0])
    q1 = np.trapezoid(r["Q1"][late], t[late]) / (t[-1] - t[late][0])
    q2 = np.trapezoid(r["Q2"][late], t[late]) / (t[-1] - t[late][0])
    assert q1 > 0 > q2, "flow must enter chamber 1 and leave chamber 2"
    assert v_mean == pytest.approx(q1 / area, rel=0.1)
    assert v_mean == pytest.approx(-q2 / area, rel=0.1)
    # pushing up takes the higher pressure under the piston (mean over the motion)
    dp = np.trapezoid((r["P1"] - r["P2"])[late], t[late]) / (t[-1] - t[late][0])
    assert dp > 0, f"mean P1 - P2 = {dp} Pa"
    assert r["P1"][-1] > r["P2"][-1]


def test_controller_is_saturated_proportional(fmus):
    kp = 500.0
    # y_ref ramps from -30 mm to +30 mm with y = 2 mm: Kp (y_ref - y) spans -16 V .. 14 V
    inp = signals([(0.0, -0.03, 0.002), (0.1, 0.03, 0.002)], ["y_ref", "y"])
    r = simulate_fmu(str(fmus["controller"].path), stop_time=0.1, input=inp,
                     start_values={"Kp": kp}, output=["y_ref", "y", "u1", "u2"])
    expected = np.clip(kp * (r["y_ref"] - r["y"]), -10.0, 10.0)
    assert np.max(np.abs(r["u1"] - expected)) < 1e-9
    assert np.array_equal(r["u2"], -r["u1"])
    assert r["u1"].min() == -10.0 and r["u1"].max() == 10.0
    linear = np.abs(expected) < 9.9
    assert linear.sum() > 20, "the ramp must cross the linear range"


@pytest.mark.parametrize("u", [10.0, -10.0])
def test_servovalve_gives_rated_flow_at_rated_command_and_land_drop(fmus, u):
    # 19 L/min at 10 V and 35 bar across one land (70 bar over both lands)
    p_p, p_t = 210 * BAR, 2 * BAR
    if u > 0:  # P -> A and B -> T open
        p_a, p_b = p_p - 35 * BAR, p_t + 35 * BAR
    else:  # P -> B and A -> T open
        p_a, p_b = p_t + 35 * BAR, p_p - 35 * BAR
    # constant inputs as start values: fmpy's interpolation of a constant 10 V input column
    # yields 10.000000000000002 V, which the FMU refuses as out of bounds
    r = simulate_fmu(str(fmus["servovalve"].path), stop_time=0.02,
                     start_values={"u": u, "P_P": p_p, "P_T": p_t, "P_A": p_a, "P_B": p_b})
    q_a, q_b, x_s = r["Q_A"][-1], r["Q_B"][-1], r["x_s"][-1]
    sign = np.sign(u)
    assert sign * q_a == pytest.approx(19 * LPM, rel=0.03), f"Q_A = {q_a / LPM} L/min"
    assert -sign * q_b == pytest.approx(19 * LPM, rel=0.03), f"Q_B = {q_b / LPM} L/min"
    assert sign * x_s > 0


def test_servovalve_closed_at_null_leaks_little(fmus):
    inp = signals([(0.0, 0.0), (0.01, 0.0)], ["u"])
    r = simulate_fmu(str(fmus["servovalve"].path), stop_time=0.01, input=inp,
                     start_values={"P_A": 150 * BAR, "P_B": 50 * BAR})
    assert abs(r["Q_A"][-1]) < 2 * LPM and abs(r["Q_B"][-1]) < 2 * LPM
    assert r["x_s"][-1] == 0.0


def test_actuator_moves_with_the_flow_it_receives(fmus):
    act = fmus["actuator"]
    area = float(act.var["actuator.area"].start)
    q = 6 * LPM
    inp = signals([(0.0, q, -q, 0.0), (0.05, q, -q, 0.0)], ["Q1", "Q2", "F_ext"])
    r = simulate_fmu(str(act.path), stop_time=0.05, input=inp, output_interval=1e-3)
    late = r["time"] >= 0.02
    v_mean = np.mean(r["v"][late])
    assert v_mean == pytest.approx(q / area, rel=0.05)
    assert r["y"][-1] > r["y"][0]
    assert r["P1"][-1] > r["P2"][-1]
