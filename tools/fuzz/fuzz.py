#!/usr/bin/env python3
"""HydroBench's own FMI fuzzer: random sequences of FMI 2.0 calls with random values on
every FMU of a directory.

Each batch of sequences runs in a child process, so a crash (a signal) or a hang (the
timeout) is seen and counted instead of taking the fuzzer down. Values are drawn from the
extremes (NaN, +-inf, +-1e308, denormals, 0), the declared bounds of each variable and a
hair beyond them, the start values and random points inside the range. The variables
come from each FMU's modelDescription.xml, so a new FMU is covered without a change here.

Invariants checked on every call:
- no crash, no hang (each batch has a deadline);
- every status is a valid fmi2Status, never fmi2Fatal (a caught panic);
- no fmi2OK with a non-finite output: after every call answered OK, every Real output
  read with an OK fmi2GetReal is finite;
- every Discard or Error answer leaves a message through the logger;
- the same sequence (same seed) gives the same statuses and values twice, bit for bit
  (each sequence runs twice in fresh instances).

    python tools/fuzz/fuzz.py --fmu-dir target/fmu --seconds 300 [--json out.json]

Figures (sequences, calls, crashes, hangs, violations by kind, CPU seconds) are printed as
one JSON object; docs/fuzz.md records a long run.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import random
import resource
import struct
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
import zipfile
from ctypes import (CDLL, CFUNCTYPE, RTLD_LOCAL, Structure, byref, c_char_p, c_double,
                    c_int, c_size_t, c_uint, c_void_p, create_string_buffer)
from pathlib import Path

OK, WARNING, DISCARD, ERROR, FATAL = 0, 1, 2, 3, 4
EXTREMES = [math.nan, math.inf, -math.inf, 1e308, -1e308, 5e-324, -5e-324, 0.0, -0.0, 1e200, -1e200]
STEPS = [1e-15, 1e-9, 1e-6, 1e-4, 1e-3, 1e-3, 1e-3, 1e-2, 0.05]
BAD_STEPS = [0.0, -1e-3, math.nan, math.inf]
TOLERANCES = [1e-6, 1e-4, 1e-9, 1e-12, 1e-2, 0.0, -1e-6, math.nan, math.inf, 1.0]
STARTS = [0.0, 0.0, 1.0, 1e9, 1.7e9, -5.0, math.nan]


# --- what an FMU offers, from its model description ---------------------------------------

def describe(d: Path) -> dict:
    root = ET.parse(d / "modelDescription.xml").getroot()
    ident = root.find("CoSimulation").get("modelIdentifier")
    variables = []
    for sv in root.find("ModelVariables"):
        kind = next(iter(sv))
        num = lambda k: float(kind.get(k)) if kind.get(k) is not None else None  # noqa: E731
        variables.append({
            "name": sv.get("name"), "vr": int(sv.get("valueReference")),
            "type": kind.tag, "causality": sv.get("causality", "local"),
            "min": num("min"), "max": num("max"), "start": num("start") if kind.tag != "Boolean" else None,
        })
    return {"lib": str(d / "binaries" / "linux64" / f"{ident}.so"), "guid": root.get("guid"),
            "resources": (d / "resources").as_uri(), "variables": variables}


# --- the C ABI ---------------------------------------------------------------------------

# The FMUs call the logger as logger(env, name, status, category, "%s", message): a
# fixed-argument callback with the message as sixth argument reads it on x86-64 and
# aarch64 (variadic and fixed integer arguments share registers there).
LOGGER = CFUNCTYPE(None, c_void_p, c_char_p, c_int, c_char_p, c_char_p, c_char_p)


class Callbacks(Structure):
    _fields_ = [("logger", LOGGER), ("allocateMemory", c_void_p), ("freeMemory", c_void_p),
                ("stepFinished", c_void_p), ("componentEnvironment", c_void_p)]


MESSAGES: list[int] = []
STEPS_OK = [0]


def _log(env, name, status, category, fmt, msg):
    MESSAGES.append(status)


_LOGGER = LOGGER(_log)
_P = c_void_p
PROTOS = {
    "fmi2Instantiate": (_P, [c_char_p, c_int, c_char_p, c_char_p, _P, c_int, c_int]),
    "fmi2FreeInstance": (None, [_P]),
    "fmi2SetupExperiment": (c_int, [_P, c_int, c_double, c_double, c_int, c_double]),
    "fmi2EnterInitializationMode": (c_int, [_P]),
    "fmi2ExitInitializationMode": (c_int, [_P]),
    "fmi2Terminate": (c_int, [_P]),
    "fmi2Reset": (c_int, [_P]),
    "fmi2GetReal": (c_int, [_P, _P, c_size_t, _P]),
    "fmi2GetInteger": (c_int, [_P, _P, c_size_t, _P]),
    "fmi2GetBoolean": (c_int, [_P, _P, c_size_t, _P]),
    "fmi2SetReal": (c_int, [_P, _P, c_size_t, _P]),
    "fmi2SetInteger": (c_int, [_P, _P, c_size_t, _P]),
    "fmi2SetBoolean": (c_int, [_P, _P, c_size_t, _P]),
    "fmi2DoStep": (c_int, [_P, c_double, c_double, c_int]),
    "fmi2GetFMUstate": (c_int, [_P, _P]),
    "fmi2SetFMUstate": (c_int, [_P, _P]),
    "fmi2FreeFMUstate": (c_int, [_P, _P]),
    "fmi2SerializedFMUstateSize": (c_int, [_P, _P, _P]),
    "fmi2SerializeFMUstate": (c_int, [_P, _P, _P, c_size_t]),
    "fmi2DeSerializeFMUstate": (c_int, [_P, _P, c_size_t, _P]),
    "fmi2GetRealStatus": (c_int, [_P, c_int, _P]),
}


def load(lib: str):
    dll = CDLL(lib, mode=RTLD_LOCAL)
    for name, (res, args) in PROTOS.items():
        f = getattr(dll, name)
        f.restype, f.argtypes = res, args
    return dll


def bits(x: float) -> bytes:
    return struct.pack("<d", x)


# --- one sequence ------------------------------------------------------------------------

class Sequence:
    """Runs `n` random calls on one FMU from `seed`; returns the trace digest and the
    invariant violations seen."""

    def __init__(self, dll, fmu: dict, seed: int, n: int):
        self.dll, self.fmu, self.rng, self.n = dll, fmu, random.Random(seed), n
        self.trace = hashlib.sha256()
        self.violations: list[str] = []
        self.calls = 0
        self.reals = [v for v in fmu["variables"] if v["type"] == "Real"]
        self.outputs = [v for v in self.reals if v["causality"] == "output"]
        self.settable = [v for v in self.reals if v["causality"] in ("input", "parameter")]
        self.ints = [v for v in fmu["variables"] if v["type"] in ("Integer", "Enumeration")]
        self.bools = [v for v in fmu["variables"] if v["type"] == "Boolean"]
        self.cb = Callbacks(_LOGGER, None, None, None, None)
        self.c = None
        self.states: list[c_void_p] = []
        self.blobs: list[bytes] = []
        self.t = 0.0

    def record(self, call: str, status: int, *values) -> None:
        self.calls += 1
        self.trace.update(call.encode() + bytes([status & 0xFF]))
        for v in values:
            self.trace.update(bits(v) if isinstance(v, float) else str(v).encode())
        if status not in (OK, WARNING, DISCARD, ERROR, FATAL):
            self.violations.append(f"{call}: invalid status {status}")
        if status == FATAL:
            self.violations.append(f"{call}: fmi2Fatal (a caught panic)")

    def call(self, name: str, *args) -> int:
        before = len(MESSAGES)
        status = getattr(self.dll, name)(self.c, *args)
        if status in (DISCARD, ERROR) and not any(m >= DISCARD for m in MESSAGES[before:]):
            self.violations.append(f"{name}: {status} without a message")
        return status

    def value(self, v: dict) -> float:
        r = self.rng.random()
        lo, hi = v.get("min"), v.get("max")
        if r < 0.15:
            return self.rng.choice(EXTREMES)
        if r < 0.45 and (lo is not None or hi is not None):
            b = self.rng.choice([x for x in (lo, hi) if x is not None])
            return self.rng.choice([b, b, b + 1e-6 * max(abs(b), 1.0), b - 1e-6 * max(abs(b), 1.0)])
        if r < 0.6 and v.get("start") is not None:
            return v["start"]
        a = lo if lo is not None else -1e3
        b = hi if hi is not None else 1e3
        return self.rng.uniform(a, b) if math.isfinite(a) and math.isfinite(b) and a <= b else 0.0

    def check_outputs(self, after: str) -> None:
        if not self.outputs:
            return
        n = len(self.outputs)
        vr = (c_uint * n)(*[v["vr"] for v in self.outputs])
        out = (c_double * n)()
        status = self.call("fmi2GetReal", vr, n, out)
        self.record("outputs", status, *(list(out) if status == OK else []))
        if status == OK:
            bad = [v["name"] for v, x in zip(self.outputs, out) if not math.isfinite(x)]
            if bad:
                self.violations.append(f"fmi2OK with non-finite outputs {bad} after {after}")

    def instantiate(self) -> None:
        f = self.fmu
        self.c = self.dll.fmi2Instantiate(b"fuzz", 1, f["guid"].encode(), f["resources"].encode(),
                                          byref(self.cb), 0, self.rng.random() < 0.3)
        self.record("instantiate", 0 if self.c else 3)
        self.t = 0.0

    def free_all(self) -> None:
        for st in self.states:
            self.dll.fmi2FreeFMUstate(self.c, byref(st))
        self.states.clear()
        if self.c:
            self.dll.fmi2FreeInstance(self.c)
        self.c = None

    def run(self) -> tuple[str, list[str], int]:
        self.instantiate()
        # most sequences start from a legal initialization, so that the steps, states and
        # outputs of a running instance get their share of the calls
        if self.c and self.rng.random() < 0.85:
            for op in (self.set_real, self.legal_setup, self.enter, self.set_real, self.exit):
                op()
        # weights: a running instance's calls often, the life-cycle calls (which end a
        # run when out of order) rarely
        ops = [(self.setup, 1), (self.enter, 1), (self.exit, 1), (self.terminate, 1),
               (self.reset, 1), (self.reinstantiate, 1), (self.set_real, 8), (self.set_int, 1),
               (self.set_bool, 1), (self.get_real, 3), (self.do_step, 14), (self.get_state, 2),
               (self.set_state, 2), (self.free_state, 1), (self.serialize, 2),
               (self.deserialize, 2), (self.status, 1)]
        funcs, weights = zip(*ops)
        for _ in range(self.n):
            if not self.c:
                self.instantiate()
                continue
            op = self.rng.choices(funcs, weights)[0]
            status = op()
            if status == OK:
                self.check_outputs(op.__name__)
        self.free_all()
        return self.trace.hexdigest(), self.violations, self.calls

    # --- the calls --------------------------------------------------------------------
    def setup(self) -> int:
        tol_defined = self.rng.random() < 0.5
        tol = self.rng.choice(TOLERANCES)
        start = self.rng.choice(STARTS)
        stop_defined = self.rng.random() < 0.3
        stop = start + self.rng.choice([1.0, 0.1, -1.0, math.nan]) if math.isfinite(start) else 1.0
        s = self.call("fmi2SetupExperiment", int(tol_defined), tol, start, int(stop_defined), stop)
        if s == OK:
            self.t = start
        self.record("setup", s)
        return s

    def legal_setup(self) -> int:
        tol_defined = self.rng.random() < 0.5
        start = self.rng.choice([x for x in STARTS if math.isfinite(x)])
        s = self.call("fmi2SetupExperiment", int(tol_defined), 1e-6, start, 0, 0.0)
        if s == OK:
            self.t = start
        self.record("setup", s)
        return s

    def enter(self) -> int:
        s = self.call("fmi2EnterInitializationMode")
        self.record("enter", s)
        return s

    def exit(self) -> int:
        s = self.call("fmi2ExitInitializationMode")
        self.record("exit", s)
        return s

    def set_real(self) -> int:
        k = self.rng.randint(1, 3)
        # outputs are not settable (an error that ends the instance): one call in ten
        pool = self.reals if self.rng.random() < 0.1 or not self.settable else self.settable
        vs = [self.rng.choice(pool) for _ in range(k)]
        xs = [self.value(v) for v in vs]
        s = self.call("fmi2SetReal", (c_uint * k)(*[v["vr"] for v in vs]), k, (c_double * k)(*xs))
        self.record("set_real", s, *[v["name"] for v in vs], *xs)
        return s

    def set_int(self) -> int:
        if not self.ints:
            return ERROR
        v = self.rng.choice(self.ints)
        x = self.rng.choice([int(v["min"] or 0), int(v["max"] or 0), 0, -1, 7, 2**31 - 1, -2**31,
                             int(v["start"] or 0)])
        s = self.call("fmi2SetInteger", (c_uint * 1)(v["vr"]), 1, (c_int * 1)(x))
        self.record("set_int", s, v["name"], x)
        return s

    def set_bool(self) -> int:
        if not self.bools:
            return ERROR
        v = self.rng.choice(self.bools)
        x = self.rng.choice([0, 1, 2, -1])
        s = self.call("fmi2SetBoolean", (c_uint * 1)(v["vr"]), 1, (c_int * 1)(x))
        self.record("set_bool", s, v["name"], x)
        return s

    def get_real(self) -> int:
        v = self.rng.choice(self.reals + [{"vr": 999999, "name": "unknown"}])
        out = (c_double * 1)()
        s = self.call("fmi2GetReal", (c_uint * 1)(v["vr"]), 1, out)
        self.record("get_real", s, v["name"], *([out[0]] if s == OK else []))
        if s == OK and not math.isfinite(out[0]):
            self.violations.append(f"fmi2GetReal OK with {v['name']} = {out[0]}")
        return s

    def do_step(self) -> int:
        h = self.rng.choice(STEPS) if self.rng.random() < 0.95 else self.rng.choice(BAD_STEPS)
        t = self.t if self.rng.random() < 0.95 else self.rng.choice([self.t + 0.5, self.t - 1e-3, math.nan])
        s = self.call("fmi2DoStep", t, h, 1)
        if s == OK:
            self.t = t + h
            STEPS_OK[0] += 1
        self.record("do_step", s, t, h)
        return s

    def get_state(self) -> int:
        st = c_void_p()
        if self.states and self.rng.random() < 0.3:
            st = self.states.pop(self.rng.randrange(len(self.states)))
        s = self.call("fmi2GetFMUstate", byref(st))
        if st.value:
            self.states.append(st)
        self.record("get_state", s)
        return s

    def set_state(self) -> int:
        st = self.rng.choice(self.states) if self.states else c_void_p()
        s = self.call("fmi2SetFMUstate", st)
        self.record("set_state", s)
        # the clock follows the state; the fuzzer reads it back
        if s == OK:
            t = c_double()
            if self.dll.fmi2GetRealStatus(self.c, 2, byref(t)) == OK:
                self.t = t.value
        return s

    def free_state(self) -> int:
        if not self.states:
            return ERROR
        st = self.states.pop(self.rng.randrange(len(self.states)))
        s = self.call("fmi2FreeFMUstate", byref(st))
        self.record("free_state", s)
        return s

    def serialize(self) -> int:
        if not self.states:
            return ERROR
        st = self.rng.choice(self.states)
        size = c_size_t()
        s = self.call("fmi2SerializedFMUstateSize", st, byref(size))
        if s == OK:
            buf = create_string_buffer(size.value)
            s = self.call("fmi2SerializeFMUstate", st, buf, size)
            if s == OK:
                self.blobs.append(buf.raw)
        self.record("serialize", s)
        return s

    def deserialize(self) -> int:
        if not self.blobs:
            return ERROR
        data = bytearray(self.rng.choice(self.blobs))
        if self.rng.random() < 0.5 and data:
            for _ in range(self.rng.randint(1, 4)):
                data[self.rng.randrange(len(data))] = self.rng.randrange(256)
        if self.rng.random() < 0.1:
            data = data[: self.rng.randrange(len(data) + 1)]
        st = c_void_p()
        buf = create_string_buffer(bytes(data), len(data))
        s = self.call("fmi2DeSerializeFMUstate", buf, len(data), byref(st))
        if st.value:
            self.states.append(st)
        self.record("deserialize", s)
        return s

    def terminate(self) -> int:
        s = self.call("fmi2Terminate")
        self.record("terminate", s)
        return s

    def reset(self) -> int:
        s = self.call("fmi2Reset")
        if s == OK:
            self.t = 0.0
        self.record("reset", s)
        return s

    def status(self) -> int:
        t = c_double()
        s = self.call("fmi2GetRealStatus", 2, byref(t))
        self.record("status", s, *([t.value] if s == OK else []))
        return s

    def reinstantiate(self) -> int:
        self.free_all()
        self.instantiate()
        return ERROR  # nothing to check on a fresh instance


# --- child: one batch ------------------------------------------------------------------------

def child(fmu_dir: str, seeds: list[int], calls: int) -> dict:
    fmu = describe(Path(fmu_dir))
    dll = load(fmu["lib"])
    out = {"sequences": 0, "calls": 0, "violations": []}
    for seed in seeds:
        first = Sequence(dll, fmu, seed, calls).run()
        second = Sequence(dll, fmu, seed, calls).run()
        out["sequences"] += 1
        out["calls"] += first[2] + second[2]
        out["violations"] += [f"seed {seed}: {v}" for v in first[1]]
        out["steps_ok"] = STEPS_OK[0]
        if first[0] != second[0]:
            out["violations"].append(f"seed {seed}: the same sequence gave different results")
    return out


# --- parent ----------------------------------------------------------------------------------

def unpack_all(fmu_dir: Path, into: Path) -> dict[str, Path]:
    found = {}
    for f in sorted(fmu_dir.glob("*.fmu")):
        d = into / f.stem
        with zipfile.ZipFile(f) as z:
            z.extractall(d)
        found[f.stem] = d
    return found


def run(fmu_dir: Path, seconds: float, seed: int, batch: int, calls: int, timeout: float) -> dict:
    start = time.monotonic()
    totals = {"fmus": [], "sequences": 0, "calls": 0, "crashes": 0, "hangs": 0,
              "non_finite_ok": 0, "nondeterministic": 0, "other_violations": 0, "findings": []}
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    with tempfile.TemporaryDirectory() as tmp:
        fmus = unpack_all(fmu_dir, Path(tmp))
        totals["fmus"] = list(fmus)
        if not fmus:
            raise SystemExit(f"no *.fmu in {fmu_dir}")
        next_seed = seed
        while time.monotonic() - start < seconds:
            for name, d in fmus.items():
                seeds = list(range(next_seed, next_seed + batch))
                next_seed += batch
                cmd = [sys.executable, __file__, "--child", str(d), "--seeds",
                       ",".join(map(str, seeds)), "--calls", str(calls)]
                try:
                    p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
                except subprocess.TimeoutExpired:
                    totals["hangs"] += 1
                    totals["findings"].append(f"{name} seeds {seeds}: no answer in {timeout} s")
                    continue
                if p.returncode != 0:
                    totals["crashes"] += 1
                    totals["findings"].append(
                        f"{name} seeds {seeds}: exit {p.returncode}: {p.stderr.strip()[-300:]}")
                    continue
                r = json.loads(p.stdout.strip().splitlines()[-1])
                totals["sequences"] += r["sequences"]
                totals["calls"] += r["calls"]
                totals["steps_ok"] = totals.get("steps_ok", 0) + r.get("steps_ok", 0)
                for v in r["violations"]:
                    if "non-finite" in v or "OK with" in v:
                        totals["non_finite_ok"] += 1
                    elif "different results" in v:
                        totals["nondeterministic"] += 1
                    else:
                        totals["other_violations"] += 1
                    totals["findings"].append(f"{name} {v}")
                if time.monotonic() - start >= seconds:
                    break
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    totals["cpu_seconds"] = round(cpu1.ru_utime + cpu1.ru_stime - cpu0.ru_utime - cpu0.ru_stime, 1)
    totals["wall_seconds"] = round(time.monotonic() - start, 1)
    totals["findings"] = totals["findings"][:50]
    return totals


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fmu-dir", type=Path, default=Path(__file__).resolve().parents[2] / "target" / "fmu")
    ap.add_argument("--seconds", type=float, default=60.0, help="run batches until this much time has passed")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--batch", type=int, default=4, help="sequences per child process")
    ap.add_argument("--calls", type=int, default=60, help="calls per sequence")
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds a batch may take")
    ap.add_argument("--json", type=Path, help="also write the figures here")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--seeds", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        print(json.dumps(child(a.child, [int(s) for s in a.seeds.split(",")], a.calls)))
        return
    r = run(a.fmu_dir, a.seconds, a.seed, a.batch, a.calls, a.timeout)
    text = json.dumps(r, indent=1)
    print(text)
    if a.json:
        a.json.write_text(text + "\n")


if __name__ == "__main__":
    os.environ.setdefault("RUST_BACKTRACE", "0")
    main()
