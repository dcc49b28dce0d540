"""What a worker runs: one simulation of the FMU at one point, and its metrics.

It depends on numpy, fmpy and the standard library only, and takes and returns plain
data (dicts, lists, numpy arrays). The FMU travels as bytes once per worker and is
extracted into a per-host cache keyed by its SHA-256.

One point: instantiate the FMU, set the start values, initialise, then at every
communication point t_k = k * step set the inputs from the scenario's table and step;
read y, P1, P2 (and Q_supply when the FMU has it) at every point. The wall-clock budget
is checked between steps: a point that exceeds it stops and is recorded as a timeout.
"""
from __future__ import annotations

import math
import os
import shutil
import socket
import tempfile
import time
import zipfile
from ctypes import byref
from pathlib import Path
from typing import Any

import numpy as np

METRICS: dict[str, str] = {
    "transient_max": "largest |y - y_ref| over the transient windows (m)",
    "transient_rms": "RMS of y - y_ref over the transient windows (m)",
    "transient_std": "standard deviation of y - y_ref over the transient windows (m)",
    "static_mean": "mean of y - y_ref over the static windows: steady-state error (m)",
    "static_std": "standard deviation of y - y_ref over the static windows (m)",
    "static_max": "largest |y - y_ref| over the static windows (m)",
    "peak_pressure": "largest chamber pressure, P1 or P2, over the run (Pa, absolute)",
    "energy": "energy drawn from the supply, integral of P_supply * Q_supply dt (J)",
}

#: Outputs the metrics read; Q_supply is optional (older FMUs lack it).
OUTPUTS = ("y", "P1", "P2")
SUPPLY_FLOW = "Q_supply"
# s, tolerance on window edges, as WINDOW_EDGE in model/src/control/scenario.rs: sample
# times meant to sit on an edge carry round-off of either sign
WINDOW_EDGE = 1e-9
SUPPLY_PRESSURE = "P_supply"


class PointTimeout(Exception):
    pass


# --- the FMU, once per worker process ------------------------------------------------

#: What this process keeps across points: loaded FMUs (SHA-256 -> (folder, model
#: description)), the FMI callbacks and the FMU's log messages of the current point.
_STATE: dict[str, Any] = {"loaded": {}, "log": [], "callbacks": None}


def _state() -> dict[str, Any]:
    return _STATE


def _unpacked(sha: str, blob: bytes | None, path: str | None) -> tuple[str, Any]:
    """(extracted folder, model description) of the FMU with this SHA-256, extracted once
    per host into the temporary folder and read once per process."""
    from fmpy import read_model_description

    loaded = _state()["loaded"]
    if sha in loaded:
        return loaded[sha]
    root = Path(tempfile.gettempdir()) / "hbench-sweep-fmu"
    target = root / sha
    if not (target / "modelDescription.xml").is_file():
        root.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(dir=root, prefix=f".{sha[:12]}-"))
        if blob is not None:
            import io

            zipfile.ZipFile(io.BytesIO(blob)).extractall(staging)
        else:
            zipfile.ZipFile(path).extractall(staging)
        try:
            staging.rename(target)
        except OSError:  # another process of this host extracted it first
            shutil.rmtree(staging, ignore_errors=True)
    md = read_model_description(str(target), validate=False)
    loaded[sha] = (str(target), md)
    return loaded[sha]


def _callbacks():
    """FMI callbacks whose logger keeps the FMU's messages for the point's record."""
    state = _state()
    if state["callbacks"] is None:
        from fmpy import calloc, free
        from fmpy.fmi2 import (
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )
        from fmpy.logging import addLoggerProxy

        log = state["log"]

        def keep(env, instance, status, category, message):
            log.append(message.decode("utf-8", "replace") if message else "")

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(keep)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(byref(cb))
        state["callbacks"] = (cb, keep)  # the Python callable must outlive the struct
    return state["callbacks"][0]


# --- inputs and metrics ----------------------------------------------------------------

def sample_inputs(table: dict[str, np.ndarray], times: np.ndarray) -> dict[str, np.ndarray]:
    """Each input column at the communication times: linear between rows, and at a row
    time given twice (a jump) the later row's value."""
    t = np.asarray(table["time"], dtype=float)
    i = np.clip(np.searchsorted(t, times, side="right") - 1, 0, len(t) - 1)
    j = np.minimum(i + 1, len(t) - 1)
    span = t[j] - t[i]
    w = np.where(span > 0, np.clip((times - t[i]) / np.where(span > 0, span, 1.0), 0.0, 1.0), 0.0)
    return {
        name: np.asarray(col, dtype=float)[i] * (1 - w) + np.asarray(col, dtype=float)[j] * w
        for name, col in table.items()
        if name != "time"
    }


def _window_mask(times: np.ndarray, windows: list[dict], kind: str) -> np.ndarray:
    mask = np.zeros(times.shape, dtype=bool)
    for w in windows:
        if w["kind"] == kind:
            # half-open with the same edge tolerance as scenario::Window::contains in Rust
            mask |= (times >= w["start"] - WINDOW_EDGE) & (times < w["end"] - WINDOW_EDGE)
    return mask


def metrics(series: dict[str, np.ndarray], windows: list[dict], wanted: list[str],
            p_supply: float) -> tuple[dict[str, float], list[str]]:
    """The wanted metrics of one run, and notes on those that could not be computed."""
    t = series["time"]
    err = series["y"] - series["y_ref"]
    out: dict[str, float] = {}
    notes: list[str] = []
    for kind in ("transient", "static"):
        mask = _window_mask(t, windows, kind)
        names = [m for m in wanted if m.startswith(kind + "_")]
        if names and not mask.any():
            notes.append(f"no {kind} window inside the run: {', '.join(names)} skipped")
            out.update({m: math.nan for m in names})
            continue
        e = err[mask]
        stats = {
            "max": float(np.max(np.abs(e))) if e.size else math.nan,
            "rms": float(np.sqrt(np.mean(e**2))) if e.size else math.nan,
            "std": float(np.std(e)) if e.size else math.nan,
            "mean": float(np.mean(e)) if e.size else math.nan,
        }
        for m in names:
            out[m] = stats[m.split("_", 1)[1]]
    if "peak_pressure" in wanted:
        out["peak_pressure"] = float(max(np.max(series["P1"]), np.max(series["P2"])))
    if "energy" in wanted:
        if SUPPLY_FLOW in series:
            q = series[SUPPLY_FLOW]
            # each sample's flow over the interval that ends at it, as scenario::Metrics
            out["energy"] = float(p_supply * np.sum(q[1:] * np.diff(t)))
        else:
            out["energy"] = math.nan
            notes.append(f"the FMU has no output {SUPPLY_FLOW}: energy skipped")
    return out, notes


# --- one point -------------------------------------------------------------------------

def simulate(job: dict, shared: dict) -> dict[str, np.ndarray]:
    """Run the FMU at one point; the recorded series at the communication points."""
    from fmpy.fmi2 import FMU2Slave

    folder, md = _unpacked(shared["fmu_sha"], shared.get("fmu_bytes"), shared.get("fmu_path"))
    var = {v.name: v for v in md.modelVariables}
    step, stop = shared["step"], shared["stop_time"]
    n = int(round(stop / step))
    times = np.arange(n + 1) * step
    inputs = sample_inputs(shared["inputs"], times)
    in_names = [k for k in inputs if k in var and var[k].causality == "input"]
    in_vrs = [var[k].valueReference for k in in_names]
    in_rows = np.stack([inputs[k] for k in in_names], axis=1) if in_names else np.zeros((n + 1, 0))
    out_names = list(OUTPUTS) + ([SUPPLY_FLOW] if SUPPLY_FLOW in var else [])
    out_vrs = [var[k].valueReference for k in out_names]
    rec = np.empty((n + 1, len(out_names)))

    deadline = time.perf_counter() + shared["timeout"]
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=folder,
                    modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName=f"sweep-{job['id']}")
    _state()["log"].clear()
    fmu.instantiate(callbacks=_callbacks())
    try:
        fmu.setupExperiment(tolerance=shared.get("tolerance"), startTime=0.0)
        for name, value in job["start_values"].items():
            v = var[name]
            if v.type == "Real":
                fmu.setReal([v.valueReference], [float(value)])
            elif v.type == "Boolean":
                fmu.setBoolean([v.valueReference], [bool(value)])
            else:
                fmu.setInteger([v.valueReference], [int(value)])
        if in_names:
            fmu.setReal(in_vrs, list(in_rows[0]))
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        rec[0] = fmu.getReal(out_vrs)
        for k in range(n):
            if in_names:
                fmu.setReal(in_vrs, list(in_rows[k]))
            fmu.doStep(float(times[k]), step)
            rec[k + 1] = fmu.getReal(out_vrs)
            if k % 32 == 0 and time.perf_counter() > deadline:
                raise PointTimeout(f"stopped at t = {times[k + 1]:.4g} s of {stop:.4g} s "
                                   f"after the {shared['timeout']:g} s budget")
        fmu.terminate()
    finally:
        fmu.freeInstance()
    series = {"time": times, "y_ref": inputs.get("y_ref", np.zeros_like(times))}
    series.update({name: rec[:, j] for j, name in enumerate(out_names)})
    return series


def evaluate(job: dict, shared: dict) -> dict:
    """One point's record: {"id", "status" (ok, failed, timeout), "metrics", "error",
    "notes", "wall_time", "worker"}. Never raises for a failure of the simulation."""
    started = time.perf_counter()
    record: dict[str, Any] = {"id": job["id"], "status": "ok", "metrics": {}, "error": "", "notes": []}
    try:
        series = simulate(job, shared)
        p_supply = float(job["start_values"].get(SUPPLY_PRESSURE, shared["p_supply"]))
        record["metrics"], record["notes"] = metrics(series, shared["windows"], shared["metrics"], p_supply)
    except PointTimeout as e:
        record.update(status="timeout", error=str(e))
    except Exception as e:  # the FMU refused a value, the solver failed, ...
        fmu_says = "; ".join(m for m in _state()["log"][-3:] if m)
        record.update(status="failed", error=f"{type(e).__name__}: {e}" + (f" (FMU: {fmu_says})" if fmu_says else ""))
    record["wall_time"] = time.perf_counter() - started
    record["worker"] = f"{socket.gethostname()}:{os.getpid()}"
    return record
