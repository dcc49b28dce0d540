#!/usr/bin/env python3
"""The HydroBench bench co-simulated from its component FMUs with fmpy, as bench.ssp wires
them: two servovalve.fmu instances, manifold.fmu and actuator.fmu, stepped at a fixed
communication step in Gauss-Seidel (default) or Jacobi order, under the thesis's 1 kHz
proportional control u1 = -u2 = Kp (y_ref - y) (mode 1: u2 = 0), computed here or, with
--controller, by controller.fmu inside the system (the package's ClosedLoop variants,
where reference.fmu feeds it the move the package binds; sampled at 1 ms while the plant
steps at --step): the same algorithm as `hbench cosim` (tools/hbench/src/cosim/).

    python tools/fmpy/cosim.py --ssp target/fmu/bench.ssp --controller [--mode 3]
    python tools/fmpy/cosim.py --ssp target/fmu/bench.ssp --reference out/cosim/reference_move.csv
                               [--mode 3] [--step 1e-4] [--order gauss-seidel] [--out trace.csv]
                               [--replace sv2=my_valve.fmu] [--controller]

Without --controller, the reference y_ref(t) at the control instants comes from
`hbench cosim` (reference_<experiment>.csv), which computes the 7th-order move in Rust; its
first value is the initial piston position. With --controller it is optional: the
package's reference.fmu gives the move, up to the SSD's stop time. Writes time, y_ref, y, P1, P2 (SI) at the control
instants. The SSDs connect components only; the master drives and reads
`Element.variable` (SV1.u, Actuator.y, ...).

Swapping a component: `--replace NAME=path.fmu` loads your FMU in place of the packaged one
(it must have the same connector names), or edit USER_COMPONENTS below to put Python code
there: any object with the methods of `Component` (set, get, step) will do.
"""
from __future__ import annotations

import argparse
import csv
import tempfile
import zipfile
from pathlib import Path
from xml.etree import ElementTree

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

SSD = "{http://ssp-standard.org/SSP1/SystemStructureDescription}"
SSV = "{http://ssp-standard.org/SSP1/SystemStructureParameterValues}"

CONTROL_PERIOD = 1e-3  # s, the thesis bench's sampling period
CONTROLLER = "Controller"  # the controller.fmu instance of the closed-loop variants
# where the loop is closed (tools/hbench/src/cosim/ssp/systems.rs)
U1, U2, Y, P1, P2 = "SV1.u", "SV2.u", "Actuator.y", "Actuator.P1", "Actuator.P2"
REFERENCE_Y = "Reference.y_ref"
KP = 1169.0  # V/m
U_MAX = 10.0  # V


class Component:
    """One FMU instance: set and get Real values by name, step."""

    def __init__(self, name: str, fmu_path: str, tmp: str):
        md = read_model_description(fmu_path)
        self.name = name
        self.vars = {v.name: v for v in md.modelVariables}
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(fmu_path, tmp),
                             modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate()
        self.t = 0.0

    def has(self, name: str) -> bool:
        return name in self.vars

    def set_parameter(self, name: str, value):
        v = self.vars[name]
        if v.type == "Boolean":
            self.fmu.setBoolean([v.valueReference], [bool(value)])
        elif v.type in ("Integer", "Enumeration"):
            self.fmu.setInteger([v.valueReference], [int(value)])
        else:
            self.fmu.setReal([v.valueReference], [float(value)])

    def initialize(self):
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()

    def ready(self):
        self.fmu.exitInitializationMode()

    def set(self, names: list[str], values: list[float]):
        self.fmu.setReal([self.vars[n].valueReference for n in names], list(values))

    def get(self, names: list[str]) -> list[float]:
        return self.fmu.getReal([self.vars[n].valueReference for n in names])

    def step(self, h: float):
        self.fmu.doStep(currentCommunicationPoint=self.t, communicationStepSize=h)
        self.t += h

    def free(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


# --------------------------------------------------------------------------------------
# >>> YOUR COMPONENT GOES HERE <<<
# Map a component name of bench.ssp (SV1, SV2, Manifold, Actuator) to a factory
# `f(name, fmu_path, tmp) -> object` with the methods of Component: has, set_parameter,
# initialize, ready, set, get, step, free. The object receives the inputs its SSD
# connections name (e.g. a servovalve: u, P_A, P_B; outputs Q_A, Q_B, dQ_A_dP_A,
# dQ_B_dP_B) and must give the outputs the others read. Example: your own valve FMU,
#     USER_COMPONENTS = {"SV2": lambda name, _path, tmp: Component(name, "my_valve.fmu", tmp)}
# or a Python class of yours. Empty: every component is the packaged FMU.
USER_COMPONENTS: dict = {}
# --------------------------------------------------------------------------------------


def read_system(ssp: Path, tmp: str, ssd: str = "SystemStructure.ssd"):
    """Components (name, FMU path inside the package, parameters) and connections of the
    package's SSD `ssd` (the default system, or a variant such as ClosedLoop.ssd)."""
    with zipfile.ZipFile(ssp) as z:
        z.extractall(tmp)
    root = ElementTree.parse(Path(tmp) / ssd).getroot()
    system = root.find(f"{SSD}System")
    components = []
    for c in system.find(f"{SSD}Elements").findall(f"{SSD}Component"):
        params = {}
        for p in c.iter(f"{SSV}Parameter"):
            (value,) = list(p)
            kind = value.tag.replace(SSV, "")
            text = value.get("value")
            params[p.get("name")] = {"Real": float, "Integer": int}.get(
                kind, lambda s: s in ("true", "1"))(text)
        components.append((c.get("name"), str(Path(tmp) / c.get("source")), params))
    connections = [(c.get("startElement"), c.get("startConnector"),
                    c.get("endElement"), c.get("endConnector"))
                   for c in system.find(f"{SSD}Connections").findall(f"{SSD}Connection")]
    return components, connections


class Master:
    """The fixed-step master: each component reads its inputs from its sources' outputs,
    all before anyone steps (Jacobi) or each just before it steps (Gauss-Seidel, in the
    SSD's order)."""

    def __init__(self, ssp: Path, tmp: str, mode: int, y0: float, replace: dict[str, str],
                 ssd: str = "SystemStructure.ssd"):
        components, connections = read_system(ssp, tmp, ssd)
        self.comps = []
        for name, path, params in components:
            make = USER_COMPONENTS.get(name, Component)
            c = make(name, replace.get(name, path), f"{tmp}/{name}")
            for n, v in params.items():
                c.set_parameter(n, v)
            for n, v in (("mode", mode), ("y0", y0)):
                if c.has(n) and v is not None:
                    c.set_parameter(n, v)
            self.comps.append(c)
        index = {c.name: k for k, c in enumerate(self.comps)}
        self.index = index
        # links[k]: {source index: ([source outputs], [inputs of k])}
        self.links = [dict() for _ in self.comps]
        for a, out, b, inp in connections:
            outs, ins = self.links[index[b]].setdefault(index[a], ([], []))
            outs.append(out)
            ins.append(inp)
        for c in self.comps:
            c.initialize()
        for _ in range(3):  # consistent initial inputs, as hbench does
            for k in range(len(self.comps)):
                self.pull(k)
        for c in self.comps:
            c.ready()
        # multi-rate: the controller of the closed-loop variants samples at its own period
        self.periods = {k: CONTROL_PERIOD for k, c in enumerate(self.comps)
                        if c.name == CONTROLLER}
        self.t = 0.0

    def pull(self, k: int):
        for src, (outs, ins) in self.links[k].items():
            self.comps[k].set(ins, self.comps[src].get(outs))

    def set_input(self, name: str, x: float):
        """Set the input `Element.variable`."""
        element, var = name.split(".", 1)
        self.comps[self.index[element]].set([var], [x])

    def output(self, name: str) -> float:
        """The output `Element.variable`."""
        element, var = name.split(".", 1)
        return self.comps[self.index[element]].get([var])[0]

    def step(self, h: float, order: str):
        # a sampled component whose period begins now reads its inputs first (its
        # command depends on them), steps when its period is over and holds in between
        eps = 1e-9 * h
        for k in self.periods:
            if abs(self.comps[k].t - self.t) < eps:
                self.pull(k)
        plant = [k for k in range(len(self.comps)) if k not in self.periods]
        if order == "jacobi":
            for k in plant:
                self.pull(k)
            for k in plant:
                self.comps[k].step(h)
        else:
            for k in plant:
                self.pull(k)
                self.comps[k].step(h)
        self.t += h
        for k, period in self.periods.items():
            if self.comps[k].t + period <= self.t + eps:
                self.comps[k].step(period)

    def free(self):
        for c in self.comps:
            c.free()


def read_reference(path: Path) -> list[tuple[float, float]]:
    with open(path, newline="") as f:
        return [(float(r["time"]), float(r["y_ref"])) for r in csv.DictReader(f)]


def simulate(ssp: Path, reference: list[tuple[float, float]] | None, mode: int = 3,
             step: float = 1e-4,
             order: str = "gauss-seidel", replace: dict[str, str] | None = None,
             controller: bool = False):
    """Rows (t, y_ref, y, P1, P2) at the control instants. `controller`: the package's
    closed-loop variant, controller.fmu in the system fed by reference.fmu with the move the
    package binds (`reference` then only gives the sampling instants and y_ref's column),
    instead of the law computed here."""
    sub = max(1, round(CONTROL_PERIOD / step))
    h = CONTROL_PERIOD / sub
    rows = []
    ssd = "SystemStructure.ssd"
    if controller:
        ssd = {1: "ClosedLoopMode1.ssd", 2: "ClosedLoopMode2.ssd", 3: "ClosedLoop.ssd"}[mode]
    with tempfile.TemporaryDirectory() as tmp:
        if reference is None:  # the package's own experiment: instants to its stop time
            if not controller:
                raise ValueError("without --controller a reference is needed")
            with zipfile.ZipFile(ssp) as z:
                root = ElementTree.fromstring(z.read(ssd))
            stop = float(root.find(f"{SSD}DefaultExperiment").get("stopTime"))
            reference = [(k * CONTROL_PERIOD, None)
                         for k in range(round(stop / CONTROL_PERIOD) + 1)]
        m = Master(ssp, tmp, mode, reference[0][1], replace or {}, ssd)
        try:
            for k, (t, y_ref) in enumerate(reference):
                y, p1, p2 = m.output(Y), m.output(P1), m.output(P2)
                if controller:  # what the loop follows: reference.fmu's output
                    y_ref = m.output(REFERENCE_Y)
                rows.append((t, y_ref, y, p1, p2))
                if k == len(reference) - 1:
                    break
                if not controller:
                    u = min(U_MAX, max(-U_MAX, KP * (y_ref - y)))
                    m.set_input(U1, u)
                    # mode 1 drives the actuator with SV1 alone; SV2 stays at null
                    m.set_input(U2, 0.0 if mode == 1 else -u)
                for _ in range(sub):
                    m.step(h, order)
        finally:
            m.free()
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ssp", default="target/fmu/bench.ssp")
    ap.add_argument("--reference", help="reference_<experiment>.csv of hbench cosim (optional "
                    "with --controller: the package's move)")
    ap.add_argument("--mode", type=int, default=3, choices=(1, 2, 3))
    ap.add_argument("--step", type=float, default=1e-4, help="communication step (s)")
    ap.add_argument("--order", default="gauss-seidel", choices=("gauss-seidel", "jacobi"))
    ap.add_argument("--replace", action="append", default=[], metavar="NAME=FMU",
                    help="load this FMU in place of a component of the package")
    ap.add_argument("--controller", action="store_true",
                    help="controller.fmu in the system (the package's ClosedLoop variants)")
    ap.add_argument("--out", default="out/cosim/fmpy_trace.csv")
    a = ap.parse_args()
    replace = dict(r.split("=", 1) for r in a.replace)
    reference = read_reference(Path(a.reference)) if a.reference else None
    rows = simulate(Path(a.ssp), reference, a.mode, a.step, a.order,
                    replace, a.controller)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    with open(a.out, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["time", "y_ref", "y", "P1", "P2"])
        w.writerows(rows)
    print(f"{a.out}: y(end) = {rows[-1][2] * 1e3:.3f} mm")


if __name__ == "__main__":
    main()
