"""Points, their ids, the result store and the executions (in this process, or on Dask).

Every point has a stable id: a hash of the study's fingerprint (FMU, scenario, step,
stop time, windows, metrics) and of the point's full set of start values. Records land
in DIR/results.jsonl, appended by this process only (workers return their record to
the client, which writes it): one line per finished point, so a study interrupted at
any moment resumes by skipping the ids already there, and a point that Dask re-runs
after losing a worker is still written once.
"""
from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import re
import sys
import tempfile
import time
import uuid
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable

from .evaluate import SUPPLY_PRESSURE, evaluate
from .sampling import design
from .scenario import Scenario, ScenarioError
from .study import Study, StudyError

FINISHED = ("ok", "failed", "timeout")


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def canonical(x: Any) -> str:
    """JSON with sorted keys and exact floats: the same data always hashes the same."""
    return json.dumps(x, sort_keys=True, separators=(",", ":"), default=repr)


@dataclass
class Plan:
    """A study resolved against its FMU and scenario: what each worker needs."""

    fingerprint: str
    jobs: list[dict]            # {"id", "start_values"}
    points: list[dict]          # {"id", "case", "values"}: the study's own view
    shared: dict                # evaluate()'s second argument
    factor_names: list[str] = field(default_factory=list)


def option_values(var: Any) -> dict[str, int]:
    """The named values of a selectable option: an Integer parameter whose description
    lists them as "k = name (meaning)" (fmu/src/slave.rs, enum_parameter), or an FMI
    Enumeration of an FMU of another origin."""
    if var.type == "Enumeration":
        return {item.name: int(item.value) for item in var.declaredType.items}
    return {name: int(k) for k, name in re.findall(r"(?:: |; )(\d+) = (\w+) \(", var.description or "")}


def _convert(study: Study, var: Any, table: tuple, value: Any, drawn: bool = False) -> Any:
    """A study value as the FMU takes it (enumeration names to their numbers), checked
    against the model description's type and bounds."""
    loc = study.locator
    key = table[-1] if table[0] == "parameters" else var.name
    table = table[:-1] if table[0] == "parameters" else table
    if var.type == "Boolean":
        if not isinstance(value, bool):
            raise loc.error(table, key, f"{var.name} is Boolean: give true or false, not {value!r}")
        return value
    if var.type in ("Integer", "Enumeration") and isinstance(value, str):
        items = option_values(var)
        if value not in items:
            raise loc.error(table, key, f"{value!r} is not one of {var.name}'s values: {', '.join(items)}")
        return int(items[value])
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise loc.error(table, key, f"{var.name} is {var.type}: expected a number, got {value!r}")
    if var.type in ("Integer", "Enumeration"):
        if int(value) != value:
            raise loc.error(table, key, f"{var.name} is {var.type}: expected a whole number, got {value!r}")
        value = int(value)
    else:
        value = float(value)
    lo = None if var.min is None else float(var.min)
    hi = None if var.max is None else float(var.max)
    if (lo is not None and value < lo) or (hi is not None and value > hi) or not math.isfinite(value):
        unit = f" {var.unit}" if var.unit else ""
        raise loc.error(table, key, f"{var.name} = {value!r} is outside the FMU's bounds "
                        f"[{lo}, {hi}]{unit}" + (" (bound the distribution with `min`/`max`)" if drawn else ""))
    return value


def plan(study: Study, scenario: Scenario, md: Any, fmu_sha: str) -> Plan:
    """Resolve every point of the study against the model description."""
    var = {v.name: v for v in md.modelVariables}
    loc = study.locator

    def variable(table: tuple, name: str):
        if name not in var:
            raise loc.error(table, name if table[0] != "parameters" else None,
                            f"{study.fmu.name} has no variable {name!r}")
        v = var[name]
        if v.causality != "parameter":
            raise loc.error(table, name if table[0] != "parameters" else None,
                            f"{name} is an {v.causality} of {study.fmu.name}, not a parameter")
        return v

    fmu_inputs = {v.name for v in md.modelVariables if v.causality == "input"}
    unknown = [c for c in scenario.inputs if c != "time" and c not in fmu_inputs]
    if unknown:
        raise ScenarioError(f"{scenario.source}: input column(s) {', '.join(unknown)} are not inputs of "
                            f"{study.fmu.name} (inputs: {', '.join(sorted(fmu_inputs))}); is the FMU older "
                            "than hbench? Repackage: hbench fmu --out target/fmu --force")
    base: dict[str, Any] = {}
    for name, value in scenario.start_values.items():
        v = var.get(name)
        if v is None or v.causality != "parameter":
            raise ScenarioError(f"{scenario.source}: start value {name!r} is not a parameter of "
                                f"{study.fmu.name}; is the FMU older than hbench? Repackage: "
                                "hbench fmu --out target/fmu --force")
        try:
            base[name] = _convert(study, v, ("scenario",), value)
        except StudyError as e:
            raise ScenarioError(f"{scenario.source}: start value {name}: {str(e).rsplit(': ', 1)[-1]}") from None
    for name, value in study.fixed.items():
        base[name] = _convert(study, variable(("fixed",), name), ("fixed",), value)

    default_step = md.defaultExperiment.stepSize if md.defaultExperiment else None
    step = study.step or scenario.step or float(default_step or 1e-3)
    stop = min(study.stop_time or scenario.stop_time, scenario.stop_time)
    windows = [dict(w, start=float(w["start"]), end=min(float(w["end"]), stop))
               for w in scenario.windows if float(w["start"]) < stop]
    tolerance = md.defaultExperiment.tolerance if md.defaultExperiment else None
    tolerance = None if tolerance is None else float(tolerance)
    inputs_hash = hashlib.sha256(b"".join(col.tobytes() for col in scenario.inputs.values())
                                 + canonical(list(scenario.inputs)).encode()).hexdigest()
    setup = {"fmu": fmu_sha, "inputs": inputs_hash, "step": step, "stop_time": stop,
             "tolerance": tolerance, "windows": windows, "metrics": list(study.metrics),
             "timeout": study.timeout}
    fingerprint = hashlib.sha256(canonical(setup).encode()).hexdigest()

    jobs, points, seen = [], [], set()
    factor = {f.name: f for f in study.factors}
    for point in design(study):
        values = dict(base)
        case = next((c for c in study.cases if c.label == point["case"]), None)
        if case is not None:
            for name, value in case.values.items():
                table = ("cases", case.label)
                values[name] = _convert(study, variable(table, name), table, value)
        for name, value in point["values"].items():
            v = variable(("parameters", name), name)
            if factor[name].relative:
                if v.start is None or v.type != "Real":
                    raise loc.error(("parameters", name), "relative", f"{name} has no Real start value to scale")
                value = float(v.start) * value
            values[name] = _convert(study, v, ("parameters", name), value, factor[name].distribution is not None)
        pid = hashlib.sha256(canonical([fingerprint, point["case"], values]).encode()).hexdigest()[:16]
        if pid in seen:
            continue
        seen.add(pid)
        jobs.append({"id": pid, "start_values": values})
        points.append({"id": pid, "case": point["case"], "values": point["values"]})
    p_supply = var[SUPPLY_PRESSURE].start if SUPPLY_PRESSURE in var else 0.0
    shared = {"fmu_sha": fmu_sha, "fmu_path": str(study.fmu), "inputs": scenario.inputs,
              "windows": windows, "stop_time": stop, "step": step, "tolerance": tolerance,
              "metrics": list(study.metrics), "timeout": study.timeout, "p_supply": float(p_supply)}
    return Plan(fingerprint, jobs, points, shared, [f.name for f in study.factors])


class Store:
    """DIR/study.json (the plan) and DIR/results.jsonl (one record per finished point)."""

    def __init__(self, out: Path):
        self.out = out
        self.results = out / "results.jsonl"
        self.plan_file = out / "study.json"

    def open(self, study: Study, plan_: Plan, restart: bool) -> None:
        self.out.mkdir(parents=True, exist_ok=True)
        if self.plan_file.is_file() and not restart:
            old = json.loads(self.plan_file.read_text())
            if old.get("fingerprint") != plan_.fingerprint:
                raise StudyError(
                    f"{self.out} holds results of a different setup (FMU, scenario, step, stop time, "
                    f"windows, metrics or timeout changed since {old.get('study')}): "
                    "use another --out, or --restart to discard them")
        if restart and self.results.exists():
            self.results.unlink()
        self.plan_file.write_text(json.dumps({
            "study": str(study.path), "name": study.name, "description": study.description,
            "fingerprint": plan_.fingerprint, "fmu": str(study.fmu), "factors": plan_.factor_names,
            "metrics": list(study.metrics), "points": plan_.points,
        }, indent=1, default=repr))

    def records(self) -> dict[str, dict]:
        """The last record of each point id (a torn last line from a kill is skipped)."""
        found: dict[str, dict] = {}
        if not self.results.is_file():
            return found
        with open(self.results) as f:
            for line in f:
                try:
                    rec = json.loads(line)
                except ValueError:
                    continue
                found[rec["id"]] = rec
        return found

    def append(self, record: dict) -> None:
        with open(self.results, "a") as f:
            f.write(json.dumps(record, allow_nan=True) + "\n")
            f.flush()
            os.fsync(f.fileno())


@dataclass
class RunSummary:
    mode: str
    workers: int
    points: int
    elapsed: float
    mean_point_time: float
    startup: float = 0.0  # cluster start, connection, code and FMU upload

    @property
    def points_per_second(self) -> float:
        """Over the computing phase, start-up excluded."""
        busy = self.elapsed - self.startup
        return self.points / busy if busy > 0 else math.nan

    @property
    def overhead_per_point(self) -> float:
        """Worker wall time per point outside the simulation itself (scheduling, result
        transfer, recording), start-up excluded."""
        if not self.points:
            return math.nan
        return (self.elapsed - self.startup) * self.workers / self.points - self.mean_point_time

    def as_dict(self) -> dict:
        return {"mode": self.mode, "workers": self.workers, "points": self.points,
                "elapsed_s": self.elapsed, "startup_s": self.startup,
                "points_per_s": self.points_per_second, "mean_point_s": self.mean_point_time,
                "overhead_per_point_s": self.overhead_per_point}


def _progress(total: int, initial: int, quiet: bool):
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="pt", disable=quiet, file=sys.stderr,
                dynamic_ncols=True, desc="sweep")


def run_serial(jobs: list[dict], shared: dict, on_record: Callable[[dict], None]) -> None:
    """Every point in this process, one after the other."""
    for job in jobs:
        on_record(evaluate(job, shared))


def _start_local_cluster(workers: int):
    from dask.distributed import LocalCluster

    return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                        dashboard_address=":0", silence_logs=logging.ERROR)


def _package_zip(folder: Path) -> Path:
    """This package as a zip that Client.upload_file puts on the cluster's sys.path."""
    path = folder / "hbench_sweep.zip"
    here = Path(__file__).resolve().parent
    with zipfile.ZipFile(path, "w") as z:
        for source in sorted(here.glob("*.py")):
            z.write(source, f"{here.name}/{source.name}")
    return path


def run_dask(jobs: list[dict], shared: dict, on_record: Callable[[dict], None],
             scheduler: str | None, workers: int) -> tuple[int, float]:
    """Every point on a Dask cluster: the one at `scheduler`, or a local cluster of
    `workers` single-threaded processes. Returns the number of workers used and the
    start-up time (s) before the first point could start.

    The sweep package travels to the scheduler and the workers with Client.upload_file
    (also to workers that join later) and the FMU as bytes, scattered once to every
    worker: a cluster needs the venv's packages (fmpy, numpy, dask), not this repository.
    A point whose worker dies is re-run by Dask on another worker; one that kills its
    workers repeatedly comes back as an error and is recorded as failed.
    """
    from dask.distributed import Client, as_completed

    started = time.perf_counter()
    cluster = None if scheduler else _start_local_cluster(workers)
    client = Client(scheduler or cluster, set_as_default=False)
    try:
        if scheduler:
            with tempfile.TemporaryDirectory() as tmp:
                client.upload_file(str(_package_zip(Path(tmp))))
        n_workers = len(client.scheduler_info().get("workers", {})) or workers
        payload = dict(shared)
        payload["fmu_bytes"] = Path(shared["fmu_path"]).read_bytes()
        payload.pop("fmu_path")
        shared_future = client.scatter(payload, broadcast=True, hash=False)
        startup = time.perf_counter() - started
        futures = client.map(evaluate, jobs, shared=shared_future, pure=False,
                             key=[f"hbench-point-{job['id']}-{uuid.uuid4().hex[:8]}" for job in jobs])
        by_key = {f.key: job for f, job in zip(futures, jobs)}
        for future in as_completed(futures, loop=client.loop):
            job = by_key[future.key]
            if future.status == "finished":
                record = future.result()
            else:
                error = future.exception()
                record = {"id": job["id"], "status": "failed", "metrics": {}, "notes": [],
                          "error": f"{type(error).__name__}: {error}", "wall_time": math.nan, "worker": ""}
            on_record(record)
            future.release()
        return n_workers, startup
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def execute(study: Study, plan_: Plan, store: Store, *, serial: bool, scheduler: str | None,
            workers: int, retry_failed: bool, quiet: bool) -> tuple[dict[str, dict], RunSummary | None]:
    """Run the points not finished yet; returns all records (by id) and this session's
    summary (None when nothing was left to run)."""
    done = store.records()
    keep = FINISHED if not retry_failed else ("ok",)
    finished = {pid for pid, rec in done.items() if rec.get("status") in keep}
    todo = [job for job in plan_.jobs if job["id"] not in finished]
    ids = {job["id"] for job in plan_.jobs}
    earlier = len(finished & ids)
    if not quiet:
        print(f"sweep: {study.name}: {len(plan_.jobs)} points, {earlier} finished earlier, "
              f"{len(todo)} to run", file=sys.stderr)
    if not todo:
        return {pid: rec for pid, rec in done.items() if pid in ids}, None

    session = uuid.uuid4().hex[:12]
    point_of = {p["id"]: p for p in plan_.points}
    written: set[str] = set()
    times: list[float] = []
    bar = _progress(len(plan_.jobs), earlier, quiet)
    errors = 0

    def on_record(record: dict) -> None:
        nonlocal errors
        if record["id"] in written:  # a point Dask ran twice is written once
            return
        written.add(record["id"])
        p = point_of[record["id"]]
        record = {"id": record["id"], "case": p["case"], "values": p["values"], **{
            k: v for k, v in record.items() if k != "id"}, "session": session, "recorded_at": time.time()}
        store.append(record)
        done[record["id"]] = record
        if math.isfinite(record.get("wall_time", math.nan)):
            times.append(record["wall_time"])
        if record["status"] != "ok":
            errors += 1
            bar.write(f"sweep: point {record['id']} {record['status']}: {record['error']}")
        bar.update(1)

    started = time.perf_counter()
    interrupted = False
    startup = 0.0
    try:
        if serial:
            run_serial(todo, plan_.shared, on_record)
            n_workers, mode = 1, "serial"
        else:
            n_workers, startup = run_dask(todo, plan_.shared, on_record, scheduler, workers)
            mode = f"dask {scheduler}" if scheduler else "dask local"
    except KeyboardInterrupt:
        interrupted = True
        n_workers, mode = workers, "interrupted"
    finally:
        bar.close()
    elapsed = time.perf_counter() - started
    if interrupted:
        print(f"sweep: interrupted: {len(written)} points recorded this time; run the same command "
              "again to resume", file=sys.stderr)
        raise KeyboardInterrupt
    summary = RunSummary(mode, n_workers, len(written), elapsed,
                         sum(times) / len(times) if times else math.nan, startup)
    with open(store.out / "runs.jsonl", "a") as f:
        f.write(json.dumps({"session": session, **summary.as_dict()}) + "\n")
    return {pid: rec for pid, rec in done.items() if pid in ids}, summary


def iter_records(plan_: Plan, records: dict[str, dict]) -> Iterable[dict]:
    """Records in the study's point order; points without one are pending."""
    for p in plan_.points:
        yield records.get(p["id"], {"id": p["id"], "case": p["case"], "values": p["values"],
                                    "status": "pending", "metrics": {}, "error": ""})
