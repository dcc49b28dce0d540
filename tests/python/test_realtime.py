"""The fixed-step real-time mode (`solver.fixed_step`) through bench.fmu, imported by fmpy:
it follows the adaptive solver, and it is declared last in every integrating FMU so the
value references from before it existed keep their numbers."""
from __future__ import annotations

import numpy as np
import pytest
from fmpy import simulate_fmu

BAR = 1e5


def _run(bench, fixed_step: float):
    # +-1 V on the two valves (mode 3) for 40 ms, then back to null for 20 ms
    inp = np.array(
        [(0.0, 1.0, -1.0, 0.0), (0.04, 1.0, -1.0, 0.0), (0.04, 0.0, 0.0, 0.0), (0.06, 0.0, 0.0, 0.0)],
        dtype=[("time", float), ("u1", float), ("u2", float), ("F_ext", float)],
    )
    return simulate_fmu(
        str(bench.path),
        stop_time=0.06,
        output_interval=1e-3,
        input=inp,
        start_values={"mode": 3, "solver.fixed_step": fixed_step},
        output=["y", "P1", "P2"],
    )


def test_fixed_step_follows_the_adaptive_solver_through_bench_fmu(fmus):
    bench = fmus["bench"]
    adaptive = _run(bench, 0.0)
    fixed = _run(bench, 5e-4)
    travel = np.ptp(adaptive["y"])
    assert travel > 2e-3, f"the piston moved only {travel} m"
    assert np.max(np.abs(fixed["y"] - adaptive["y"])) < 0.01 * travel
    for p in ("P1", "P2"):
        assert np.max(np.abs(fixed[p] - adaptive[p])) < 2 * BAR, p
    # the parameter changed the integration: not bit-identical to the adaptive run
    assert np.any(fixed["y"] != adaptive["y"])


@pytest.mark.parametrize("name", ["servovalve", "manifold", "actuator", "bench"])
def test_fixed_step_is_the_last_variable(fmus, name):
    u = fmus[name]
    last = max(u.md.modelVariables, key=lambda v: v.valueReference)
    assert last.name == "solver.fixed_step"
    assert last.causality == "parameter" and float(last.start) == 0.0
