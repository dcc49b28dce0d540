"""The scenario of a study: the FMU's input table, its stop time, start values and the
transient/static windows the metrics are computed over.

A named scenario comes from `hbench simulate --scenario NAME --inputs-only --out DIR`
(DIR/inputs.csv: time and one column per FMU input, SI; DIR/scenario.json: name,
description, stop_time, start_values, windows); a study can instead give its own CSV
file and windows in a [scenario] table.
"""
from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .study import ScenarioSpec, workspace_root


class ScenarioError(Exception):
    pass


#: Registry paths that the FMUs publish under another name (fmu/src/models/mod.rs,
#: `fmu_name`): scenario files may use either.
FMU_NAMES = {
    "supply_pressure": "P_supply",
    "tank_pressure": "P_tank",
    "initial_position": "y0",
    "actuator.payload_mass": "payload_mass",
}


@dataclass
class Scenario:
    name: str
    description: str
    stop_time: float
    inputs: dict[str, np.ndarray]
    windows: list[dict] = field(default_factory=list)
    start_values: dict[str, Any] = field(default_factory=dict)
    source: str = ""
    step: float | None = None


def hbench_program() -> Path | None:
    """$HBENCH (set by `hbench sweep`), the workspace's release build, or hbench on PATH."""
    candidates = [os.environ.get("HBENCH"), str(workspace_root() / "target" / "release" / "hbench"),
                  shutil.which("hbench")]
    return next((Path(c) for c in candidates if c and Path(c).is_file()), None)


def read_inputs(path: Path) -> dict[str, np.ndarray]:
    """A CSV input table: a header row with `time` first, then one column per input."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows or not rows[0] or rows[0][0].strip() != "time":
        raise ScenarioError(f"{path}: the first column must be `time`")
    header = [h.strip() for h in rows[0]]
    try:
        data = np.array([[float(x) for x in row] for row in rows[1:] if row], dtype=float)
    except ValueError as e:
        raise ScenarioError(f"{path}: {e}") from None
    if data.ndim != 2 or data.shape[0] < 1 or data.shape[1] != len(header):
        raise ScenarioError(f"{path}: expected {len(header)} numbers on each row")
    if np.any(np.diff(data[:, 0]) < 0):
        raise ScenarioError(f"{path}: time must not decrease")
    return {name: data[:, k] for k, name in enumerate(header)}


def _from_hbench(name: str, out: Path) -> None:
    """Write inputs.csv and scenario.json for a named scenario into `out`."""
    program = hbench_program()
    if program is None:
        raise ScenarioError("hbench not found (build it: cargo build --release -p hbench, or set $HBENCH)")
    cmd = [str(program), "simulate", "--scenario", name, "--inputs-only", "--out", str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode == 0:
        return
    raise ScenarioError(f"`{' '.join(cmd)}` failed: {done.stderr.strip() or done.stdout.strip()}")


def load(spec: ScenarioSpec, workdir: Path) -> Scenario:
    """The scenario of a study; named scenarios are written into workdir/scenario/."""
    if spec.inputs is not None:
        inputs = read_inputs(spec.inputs)
        meta: dict[str, Any] = {"name": spec.inputs.stem, "stop_time": float(inputs["time"][-1])}
        source = str(spec.inputs)
    else:
        out = workdir / "scenario"
        _from_hbench(spec.name, out)
        inputs = read_inputs(out / "inputs.csv")
        source = str(out / "scenario.json")
        try:
            meta = json.loads((out / "scenario.json").read_text())
        except (OSError, ValueError) as e:
            raise ScenarioError(f"{out / 'scenario.json'}: {e}") from None
    stop = spec.stop_time or float(meta.get("stop_time") or inputs["time"][-1])
    windows = list(spec.windows) if spec.windows is not None else list(meta.get("windows", []))
    start_values = {FMU_NAMES.get(k, k): v for k, v in dict(meta.get("start_values", {})).items()}
    start_values.update(spec.start_values)
    return Scenario(
        name=str(meta.get("name", spec.name)),
        description=spec.description or str(meta.get("description", "")),
        stop_time=stop,
        inputs=inputs,
        windows=windows,
        start_values=start_values,
        source=source,
        step=float(meta["communication_step"]) if meta.get("communication_step") else None,
    )
