"""The closed loop as FMUs (issue 5).

- bench_closed_loop.fmu matches controller.fmu + bench.fmu co-simulated at a 1 ms
  communication step (the issue asks for 1 % of the move amplitude);
- bench_closed_loop.fmu, driven by the input table and start values that
  `hbench simulate --inputs-only` writes, reproduces `hbench simulate`'s own run of the
  same thesis experiment: one experiment, whichever way it is run.

The reference comes from `hbench simulate`, so the 7th-order polynomial is written once,
in model/src/control/trajectory.rs.
"""
import json
import os
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave

ROOT = Path(__file__).resolve().parents[2]
HBENCH = ROOT / "target" / "release" / "hbench"
AMPLITUDE = 0.02  # the thesis moves: -10 mm -> +10 mm
LAWS = {"proportional": 1, "p_y": 3, "restricted_model": 5}


def fmu_dir() -> Path:
    return Path(os.environ.get("HB_FMU_DIR", ROOT / "target" / "fmu"))


@pytest.fixture(scope="module")
def experiments(tmp_path_factory):
    """For each law: the scenario (inputs, start values) and hbench's own trace."""
    assert HBENCH.is_file(), f"{HBENCH} missing: run `bash tools/test.sh`"
    out = {}
    for law in LAWS:
        d = tmp_path_factory.mktemp(law)
        common = ["simulate", "--scenario", "moves", "--law", law, "--out", str(d)]
        subprocess.run([HBENCH, *common, "--inputs-only"], check=True, capture_output=True)
        subprocess.run([HBENCH, *common], check=True, capture_output=True)
        scenario = json.loads((d / "scenario.json").read_text())
        inputs = np.genfromtxt(d / "inputs.csv", delimiter=",", names=True)
        trace = np.genfromtxt(d / f"moves_{law}.csv", delimiter=",", names=True)
        out[law] = (scenario, inputs, trace)
    return out


def load(name, tmp):
    path = fmu_dir() / f"{name}.fmu"
    assert path.is_file(), f"{path} missing: run `bash tools/test.sh`"
    md = read_model_description(str(path))
    unzipped = extract(str(path), unzipdir=os.path.join(tmp, name))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    return fmu, vrs


def reference_at(inputs, t):
    return [float(np.interp(t, inputs["time"], inputs[c]))
            for c in ("y_ref", "dy_ref", "d2y_ref", "d3y_ref")]


def start(fmu, vrs, law):
    if "y0" in vrs:
        fmu.setReal([vrs["y0"]], [-0.01])
    fmu.setInteger([vrs["law"]], [LAWS[law]])
    fmu.setBoolean([vrs["reference_derivatives"]], [True])


def two_fmus(law, inputs, tmp, n, step):
    """Controller and bench wired as a test-rig engineer would: the controller reads the
    bench's acquisition outputs (delayed like the real board's samples)."""
    bench, bv = load("bench", tmp)
    ctrl, cv = load("controller", tmp)
    bench.setReal([bv["y0"]], [-0.01])
    start(ctrl, cv, law)
    for f in (bench, ctrl):
        f.enterInitializationMode()
        f.exitInitializationMode()
    ys, t = [], 0.0
    refs = [cv[c] for c in ("y_ref", "dy_ref", "d2y_ref", "d3y_ref")]
    for _ in range(n):
        y, p1, p2 = bench.getReal([bv["y_meas"], bv["P1_meas"], bv["P2_meas"]])
        ctrl.setReal(refs + [cv["y"], cv["P1"], cv["P2"]], reference_at(inputs, t) + [y, p1, p2])
        u1, u2 = ctrl.getReal([cv["u1"], cv["u2"]])
        bench.setReal([bv["u1"], bv["u2"]], [u1, u2])
        bench.doStep(t, step)
        ctrl.doStep(t, step)
        t += step
        ys.append(bench.getReal([bv["y"]])[0])
    for f in (bench, ctrl):
        f.terminate()
        f.freeInstance()
    return np.array(ys)


def one_fmu(law, inputs, tmp, n, step):
    loop, lv = load("bench_closed_loop", tmp)
    start(loop, lv, law)
    loop.enterInitializationMode()
    loop.exitInitializationMode()
    ys, t = [], 0.0
    refs = [lv[c] for c in ("y_ref", "dy_ref", "d2y_ref", "d3y_ref")]
    for _ in range(n):
        loop.setReal(refs, reference_at(inputs, t))
        loop.doStep(t, step)
        t += step
        ys.append(loop.getReal([lv["y"]])[0])
    loop.terminate()
    loop.freeInstance()
    return np.array(ys)


@pytest.mark.parametrize("law", ["proportional", "p_y"])
def test_single_closed_loop_fmu_matches_two_fmus(law, experiments):
    scenario, inputs, _ = experiments[law]
    step = scenario["communication_step"]
    n = int(round(1.35 / step))  # through the first move
    with tempfile.TemporaryDirectory() as tmp:
        a = two_fmus(law, inputs, tmp, n, step)
        b = one_fmu(law, inputs, tmp, n, step)
    worst = np.abs(a - b).max()
    assert worst < 0.01 * AMPLITUDE, f"{law}: largest difference {worst * 1e6:.1f} um"
    assert abs(a[-1] - 0.01) < 1e-3, f"{law}: the move did not arrive ({a[-1]})"


@pytest.mark.parametrize("law", list(LAWS))
def test_closed_loop_fmu_reproduces_hbench_simulate(law, experiments):
    scenario, inputs, trace = experiments[law]
    res = simulate_fmu(str(fmu_dir() / "bench_closed_loop.fmu"),
                       stop_time=scenario["stop_time"],
                       step_size=scenario["communication_step"],
                       output_interval=scenario["communication_step"],
                       input=inputs, start_values=scenario["start_values"],
                       output=["y", "P1"])
    y = np.interp(trace["time"], res["time"], res["y"])
    worst = np.abs(y - trace["y"]).max()
    # both sample the same law on the same plant at the same instants: only the
    # integrator's path differs, at the tolerance's scale (about 2 um measured)
    assert worst < 1e-3 * AMPLITUDE, f"{law}: {worst * 1e6:.1f} um apart"
    moving = (trace["time"] > 1.0) & (trace["time"] < 1.3)
    error = np.abs(trace["y"] - trace["y_ref"])[moving].max()
    assert error < 0.05 * AMPLITUDE, f"{law}: tracking error {error * 1e6:.0f} um"


def test_closed_loop_fmu_validates_and_simulates_its_default_experiment():
    from fmpy.validation import validate_fmu

    path = str(fmu_dir() / "bench_closed_loop.fmu")
    assert validate_fmu(path) == []
    result = simulate_fmu(path, start_values={"y_ref": 0.005})
    # proportional control brings the piston from mid stroke to the 5 mm reference
    assert abs(result["y"][-1] - 0.005) < 2e-4, result["y"][-1]
