"""Study files: parsing and checking, with errors that name the file, line and field.

A study file is TOML:

    [study]
    name = "payload_robustness"          # used in plot titles
    description = "..."
    fmu = "bench_closed_loop.fmu"        # path, relative to this file or to the FMU folder
    scenario = "moves"                   # `hbench simulate --list`, or a [scenario] table
    sampling = "grid"                    # grid | random | lhs
    samples = 100                        # random and lhs: number of draws
    seed = 1
    metrics = ["transient_max", "transient_rms", "static_mean", "peak_pressure", "energy"]
    timeout = 120.0                      # s of wall time per point
    # stop_time = 2.6                    # optional: shorter than the scenario
    # step = 1e-3                        # communication step (s), the FMU's default

    [fixed]                              # start values of every point (FMU names)
    "actuator.mass" = 6.9
    "effect.payload" = true

    [parameters]                         # the factors, by FMU variable name
    payload_mass = { values = [0.0, 20.0, 50.0, 100.0] }           # grid levels
    Kd0 = { min = 100.0, max = 400.0, steps = 4 }                  # grid, evenly spaced
    "fluid.bulk_modulus" = { distribution = "uniform", min = 1.2e9, max = 1.8e9 }
    "friction.coulomb" = { distribution = "normal", mean = 10.0, std = 3.0, min = 0.0 }
    "sv2.rated_flow" = { distribution = "uniform", min = 0.9, max = 1.1, relative = true }

    [cases."P-Y (LG)"]                   # optional: named sets of values moved together
    law = "p_y"
    c1 = 500.0

Factors with `values` (or min/max/steps) form a grid; factors with a `distribution` are
drawn (`random` or `lhs`) and crossed with the grid and the cases. `relative = true`
multiplies the FMU's default start value. Values are SI, as in the FMU.
"""
from __future__ import annotations

import math
import os
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .evaluate import METRICS

SAMPLINGS = ("grid", "random", "lhs")
DISTRIBUTIONS = {
    "uniform": ("min", "max"),
    "loguniform": ("min", "max"),
    "normal": ("mean", "std"),
    "choice": ("values",),
}
STUDY_KEYS = {
    "name", "description", "fmu", "scenario", "sampling", "samples", "seed", "metrics",
    "timeout", "stop_time", "step",
}
SCENARIO_KEYS = {"name", "inputs", "stop_time", "windows", "start_values", "description"}
FACTOR_KEYS = {"values", "min", "max", "steps", "distribution", "mean", "std", "relative"}


def workspace_root() -> Path:
    """The repository this package lives in (tools/sweep/ -> the root)."""
    return Path(__file__).resolve().parents[2]


class StudyError(Exception):
    """A study file that cannot be run; the message names file, line and field."""


class Locator:
    """Finds the line of a table or key in a TOML text, for error messages.

    tomllib gives no positions of values, so this scans the text: it follows the
    `[table]` headers and finds `key =` lines (bare or quoted keys, dotted headers).
    """

    _KEY = re.compile(r'\s*("(?:[^"\\]|\\.)*"|\'[^\']*\'|[A-Za-z0-9_\-]+)\s*')

    def __init__(self, path: Path, text: str):
        self.path = path
        self.entries: list[tuple[tuple[str, ...], str | None, int]] = []
        table: tuple[str, ...] = ()
        for number, raw in enumerate(text.splitlines(), start=1):
            line = raw.strip()
            if line.startswith("["):
                inner = line.strip("[]").split("#")[0].strip("[] ")
                table = self._dotted(inner)
                self.entries.append((table, None, number))
            elif "=" in line and not line.startswith("#"):
                key = self._dotted(line.split("=", 1)[0])
                if key:
                    self.entries.append((table + key[:-1], key[-1], number))

    @classmethod
    def _dotted(cls, text: str) -> tuple[str, ...]:
        parts = []
        for piece in re.finditer(r'"(?:[^"\\]|\\.)*"|\'[^\']*\'|[^.]+', text):
            token = piece.group(0).strip()
            if token:
                parts.append(token.strip("\"'"))
        return tuple(parts)

    def line(self, table: tuple[str, ...], key: str | None = None) -> int:
        """Line of `key` in `table` (or of the table itself), else of the nearest
        enclosing table or key that was written; 0 if none was."""
        for t, k, n in self.entries:
            if (t, k) == (table, key):
                return n
        if key is not None:
            return self.line(table + (key,))  # a [table.key] header
        if table:
            return self.line(table[:-1], table[-1])  # `key = { ... }` one level up
        return 0

    def error(self, table: tuple[str, ...], key: str | None, message: str) -> StudyError:
        where = ".".join(f'"{p}"' if "." in p or " " in p else p for p in table + ((key,) if key else ()))
        return StudyError(f"{self.path}:{self.line(table, key)}: {where}: {message}")


@dataclass(frozen=True)
class Factor:
    """One varied FMU variable: grid levels or a distribution."""

    name: str
    values: tuple | None = None
    distribution: str | None = None
    args: dict[str, float] = field(default_factory=dict)
    relative: bool = False


@dataclass(frozen=True)
class Case:
    """A named set of FMU values that vary together (one level of the `case` factor)."""

    label: str
    values: dict[str, Any]


@dataclass(frozen=True)
class ScenarioSpec:
    """Where the input table comes from: an `hbench simulate` scenario or a CSV file."""

    name: str | None = None
    inputs: Path | None = None
    stop_time: float | None = None
    windows: tuple[dict, ...] | None = None
    start_values: dict[str, Any] = field(default_factory=dict)
    description: str = ""


@dataclass
class Study:
    path: Path
    name: str
    description: str
    fmu: Path
    scenario: ScenarioSpec
    sampling: str
    samples: int
    seed: int
    metrics: tuple[str, ...]
    timeout: float
    stop_time: float | None
    step: float | None
    fixed: dict[str, Any]
    factors: list[Factor]
    cases: list[Case]
    locator: Locator


def _number(loc: Locator, table, key, value, *, positive=False, integer=False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise loc.error(table, key, f"expected a number, got {value!r}")
    if not math.isfinite(value):
        raise loc.error(table, key, f"expected a finite number, got {value!r}")
    if integer and int(value) != value:
        raise loc.error(table, key, f"expected a whole number, got {value!r}")
    if positive and value <= 0:
        raise loc.error(table, key, f"must be positive, got {value!r}")
    return int(value) if integer else float(value)


def _unknown(loc: Locator, table, given: dict, allowed: set[str]) -> None:
    for key in given:
        if key not in allowed:
            raise loc.error(table, key, f"unknown field (expected one of {', '.join(sorted(allowed))})")


def _factor(loc: Locator, name: str, spec: Any) -> Factor:
    table = ("parameters", name)
    if not isinstance(spec, dict):
        raise loc.error(("parameters",), name,
                        "expected a table such as { values = [...] } or "
                        "{ distribution = \"uniform\", min = ..., max = ... }")
    _unknown(loc, table, spec, FACTOR_KEYS)
    relative = spec.get("relative", False)
    if not isinstance(relative, bool):
        raise loc.error(table, "relative", "expected true or false")
    dist = spec.get("distribution")
    if dist is None:
        if "values" in spec:
            values = spec["values"]
            if not isinstance(values, list) or not values:
                raise loc.error(table, "values", "expected a non-empty list")
            return Factor(name, tuple(values), relative=relative)
        if {"min", "max", "steps"} <= spec.keys():
            lo = _number(loc, table, "min", spec["min"])
            hi = _number(loc, table, "max", spec["max"])
            steps = _number(loc, table, "steps", spec["steps"], positive=True, integer=True)
            levels = [lo] if steps == 1 else [lo + (hi - lo) * k / (steps - 1) for k in range(steps)]
            return Factor(name, tuple(levels), relative=relative)
        raise loc.error(table, None, "give `values`, `min`/`max`/`steps` (grid) or a `distribution`")
    if dist not in DISTRIBUTIONS:
        raise loc.error(table, "distribution", f"unknown distribution {dist!r} (expected one of {', '.join(DISTRIBUTIONS)})")
    args: dict[str, Any] = {}
    for key in DISTRIBUTIONS[dist]:
        if key not in spec:
            raise loc.error(table, None, f"distribution {dist!r} needs `{key}`")
    if dist == "choice":
        values = spec["values"]
        if not isinstance(values, list) or not values:
            raise loc.error(table, "values", "expected a non-empty list")
        return Factor(name, None, "choice", {"values": tuple(values)}, relative)
    for key in ("min", "max", "mean", "std"):
        if key in spec:
            args[key] = _number(loc, table, key, spec[key], positive=(key == "std"))
    if "min" in args and "max" in args and args["min"] >= args["max"]:
        raise loc.error(table, "max", f"must be above min ({args['min']})")
    if dist == "loguniform" and args["min"] <= 0:
        raise loc.error(table, "min", "loguniform needs min > 0")
    return Factor(name, None, dist, args, relative)


def _scenario(loc: Locator, base: Path, spec: Any) -> ScenarioSpec:
    if isinstance(spec, str):
        return ScenarioSpec(name=spec)
    table = ("scenario",)
    if not isinstance(spec, dict):
        raise loc.error(("study",), "scenario", "expected a scenario name or a [scenario] table")
    _unknown(loc, table, spec, SCENARIO_KEYS)
    if ("name" in spec) == ("inputs" in spec):
        raise loc.error(table, None, "give either `name` (an hbench scenario) or `inputs` (a CSV file)")
    windows = spec.get("windows")
    if windows is not None:
        if not isinstance(windows, list) or not all(isinstance(w, dict) for w in windows):
            raise loc.error(table, "windows", "expected a list of { kind, start, end } tables")
        for w in windows:
            if w.get("kind") not in ("transient", "static") or not all(
                isinstance(w.get(k), (int, float)) for k in ("start", "end")
            ):
                raise loc.error(table, "windows", f"bad window {w!r}: kind is \"transient\" or \"static\", start and end in s")
        windows = tuple(windows)
    stop = spec.get("stop_time")
    if stop is not None:
        stop = _number(loc, table, "stop_time", stop, positive=True)
    start_values = spec.get("start_values", {})
    if not isinstance(start_values, dict):
        raise loc.error(table, "start_values", "expected a table of FMU start values")
    inputs = (base / spec["inputs"]).resolve() if "inputs" in spec else None
    if inputs is not None and not inputs.is_file():
        raise loc.error(table, "inputs", f"no such file: {inputs}")
    return ScenarioSpec(spec.get("name"), inputs, stop, windows, dict(start_values), str(spec.get("description", "")))


def find_fmu(name: str, base: Path) -> Path | None:
    """The FMU file: as given, relative to the study file, or in the FMU folders
    ($HB_FMU_DIR, <repo>/target/fmu, <repo>/out/fmu)."""
    given = Path(name).expanduser()
    candidates = [given] if given.is_absolute() else [base / given]
    folders = [os.environ.get("HB_FMU_DIR"), workspace_root() / "target" / "fmu", workspace_root() / "out" / "fmu"]
    candidates += [Path(f) / given.name for f in folders if f]
    return next((c.resolve() for c in candidates if c.is_file()), None)


def load(path: Path | str, fmu_override: Path | None = None) -> Study:
    """Read and check a study file (not yet against the FMU: see `points.resolve`)."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as e:
        raise StudyError(f"{path}: cannot read the study file: {e.strerror}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise StudyError(f"{path}: not valid TOML: {e}") from None
    loc = Locator(path, text)
    _unknown(loc, (), data, {"study", "fixed", "parameters", "cases", "scenario"})
    s = data.get("study")
    if not isinstance(s, dict):
        raise StudyError(f"{path}:1: study: missing [study] table")
    _unknown(loc, ("study",), s, STUDY_KEYS)
    for key in ("fmu",):
        if key not in s:
            raise loc.error(("study",), None, f"missing `{key}`")
    base = path.resolve().parent
    if fmu_override is not None:
        fmu = fmu_override.resolve()
        if not fmu.is_file():
            raise StudyError(f"--fmu {fmu_override}: no such file")
    else:
        found = find_fmu(s["fmu"], base)
        if found is None:
            raise loc.error(("study",), "fmu", f"{s['fmu']!r} not found beside the study file, in $HB_FMU_DIR, "
                            f"target/fmu or out/fmu (package the FMUs: `hbench fmu --out target/fmu`)")
        fmu = found
    if "scenario" in s and "scenario" in data:
        raise loc.error(("study",), "scenario", "given twice: as study.scenario and as a [scenario] table")
    if "scenario" not in s and "scenario" not in data:
        raise loc.error(("study",), None, "missing `scenario` (a name from `hbench simulate --list`, or a [scenario] table)")
    scenario = _scenario(loc, base, s.get("scenario", data.get("scenario")))

    sampling = s.get("sampling", "grid")
    if sampling not in SAMPLINGS:
        raise loc.error(("study",), "sampling", f"unknown sampling {sampling!r} (expected one of {', '.join(SAMPLINGS)})")
    samples = _number(loc, ("study",), "samples", s.get("samples", 1), positive=True, integer=True)
    seed = _number(loc, ("study",), "seed", s.get("seed", 0), integer=True)
    metrics = s.get("metrics", list(METRICS))
    if not isinstance(metrics, list) or not metrics:
        raise loc.error(("study",), "metrics", "expected a non-empty list of metric names")
    for m in metrics:
        if m not in METRICS:
            raise loc.error(("study",), "metrics", f"unknown metric {m!r} (known: {', '.join(METRICS)})")
    timeout = _number(loc, ("study",), "timeout", s.get("timeout", 600.0), positive=True)
    stop = s.get("stop_time")
    stop = None if stop is None else _number(loc, ("study",), "stop_time", stop, positive=True)
    step = s.get("step")
    step = None if step is None else _number(loc, ("study",), "step", step, positive=True)

    fixed = data.get("fixed", {})
    if not isinstance(fixed, dict):
        raise loc.error((), "fixed", "expected a [fixed] table of FMU start values")
    params = data.get("parameters", {})
    if not isinstance(params, dict):
        raise loc.error((), "parameters", "expected a [parameters] table")
    factors = [_factor(loc, name, spec) for name, spec in params.items()]
    cases_raw = data.get("cases", {})
    if not isinstance(cases_raw, dict) or not all(isinstance(v, dict) for v in cases_raw.values()):
        raise loc.error((), "cases", "expected [cases.\"label\"] tables of FMU values")
    cases = [Case(label, dict(values)) for label, values in cases_raw.items()]
    varied = {f.name for f in factors}
    for case in cases:
        for key in case.values:
            if key in varied:
                raise loc.error(("cases", case.label), key, "also a factor in [parameters]: set it in one place")
    drawn = [f for f in factors if f.distribution]
    if sampling == "grid" and drawn:
        raise loc.error(("parameters", drawn[0].name), "distribution",
                        "a grid study takes `values` or `min`/`max`/`steps`; set sampling = \"random\" or \"lhs\" to draw")
    if sampling != "grid" and not drawn:
        raise loc.error(("study",), "sampling", f"{sampling!r} needs at least one factor with a `distribution`")
    if not factors and not cases:
        raise loc.error((), None, "nothing varies: add [parameters] or [cases]")
    return Study(
        path=path.resolve(), name=str(s.get("name", path.stem)), description=str(s.get("description", "")),
        fmu=fmu, scenario=scenario, sampling=sampling, samples=samples, seed=seed,
        metrics=tuple(metrics), timeout=timeout, stop_time=stop, step=step, fixed=dict(fixed),
        factors=factors, cases=cases, locator=loc,
    )
