"""The bench as a system of FMUs (issue 7): the component FMUs wired by bench.ssp and
co-simulated by `hbench cosim` match bench.fmu in both coupling orders, with the master's
controller or controller.fmu in the system; the fmpy master (tools/fmpy/cosim.py) agrees
with `hbench cosim`; the SSP package validates against the SSP 1.0 XSDs.

Needs the packaged FMUs and bench.ssp in target/fmu (or $HB_FMU_DIR) and the hbench binary
(`bash tools/test.sh` makes them).
"""
from __future__ import annotations

import csv
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from lxml import etree

from conftest import ROOT, fmu_dir

sys.path.insert(0, str(ROOT / "tools" / "fmpy"))
import cosim  # noqa: E402

SCHEMA = ROOT / "tools" / "ssp" / "schema"
STEP = 1e-4  # s, the communication step
AMPLITUDE = {"move": 0.020, "sine": 3.4e-3}  # m
BAR = 1e5


@pytest.fixture(scope="module")
def ssp() -> Path:
    p = fmu_dir() / "bench.ssp"
    if not p.is_file():
        pytest.fail(f"{p} is missing: `./target/release/hbench fmu --out target/fmu --force` "
                    "writes it", pytrace=False)
    return p


def run_hbench(ssp: Path, out: Path, *extra: str):
    """`hbench cosim` at 0.1 ms, both orders, every mode and experiment: its runs and
    traces by (experiment, mode, order)."""
    exe = ROOT / "target" / "release" / "hbench"
    subprocess.run([str(exe), "cosim", "--system", str(ssp), "--bench", str(ssp.parent / "bench.fmu"),
                    "--order", "jacobi,gauss-seidel", "--steps", str(STEP), "--out", str(out),
                    *extra],
                   check=True, capture_output=True, text=True)
    runs = json.loads((out / "cosim_errors.json").read_text())["runs"]
    traces = {}
    with open(out / "cosim_traces.csv", newline="") as f:
        for r in csv.DictReader(f):
            key = (r["experiment"], int(r["mode"]), r["order"])
            traces.setdefault(key, []).append([float(r[c]) for c in ("time", "y", "P1", "P2")])
    return out, runs, traces


@pytest.fixture(scope="module")
def hbench_run(ssp, tmp_path_factory):
    """The master computes the proportional law."""
    return run_hbench(ssp, tmp_path_factory.mktemp("cosim"))


@pytest.fixture(scope="module")
def hbench_controller_run(ssp, tmp_path_factory):
    """controller.fmu in the system (the ClosedLoop variants), sampled at 1 ms."""
    return run_hbench(ssp, tmp_path_factory.mktemp("cosim_controller"), "--controller")


@pytest.mark.parametrize("run", ["hbench_run", "hbench_controller_run"])
def test_components_match_bench_fmu_at_a_tenth_of_a_millisecond(run, request):
    _, runs, _ = request.getfixturevalue(run)
    assert len(runs) == 12
    assert {r["order"] for r in runs} == {"jacobi", "gauss-seidel"}
    for r in runs:
        what = f"{r['experiment']} mode {r['mode']} {r['order']}"
        assert r["stable"], f"{what}: {r['failure']}"
        assert r["position_error_percent"] < 2.0, what
        assert r["pressure_error_bar"] < 5.0, what


def test_controller_fmu_in_the_system_closes_the_same_loop(hbench_run, hbench_controller_run):
    """controller.fmu runs the thesis's proportional law at 1 kHz on the same samples as
    the master's own law: the loops it closes are the same to rounding."""
    _, _, ours = hbench_controller_run
    _, _, theirs = hbench_run
    assert ours.keys() == theirs.keys()
    for key, trace in ours.items():
        assert len(trace) == len(theirs[key]), key
        for a, b in zip(trace, theirs[key]):
            assert abs(a[1] - b[1]) <= 1e-4 * AMPLITUDE[key[0]], (key, a[0])
            assert max(abs(a[2] - b[2]), abs(a[3] - b[3])) <= 0.01 * BAR, (key, a[0])


@pytest.mark.parametrize("experiment,mode,order,controller", [
    ("move", 1, "gauss-seidel", False), ("move", 3, "gauss-seidel", False),
    ("sine", 2, "gauss-seidel", False), ("move", 2, "jacobi", False),
    ("sine", 3, "jacobi", False), ("move", 1, "jacobi", True)])
def test_fmpy_master_agrees_with_hbench(hbench_run, hbench_controller_run, ssp, experiment, mode,
                                        order, controller):
    out, _, traces = hbench_controller_run if controller else hbench_run
    reference = cosim.read_reference(out / f"reference_{experiment}.csv")
    rows = cosim.simulate(ssp, reference, mode=mode, step=STEP, order=order, controller=controller)
    theirs = traces[(experiment, mode, order)]
    assert len(rows) == len(theirs)
    p_scale = max(max(abs(r[2]), abs(r[3])) for r in theirs)
    for ours, ref in zip(rows, theirs):
        assert ours[0] == pytest.approx(ref[0], abs=1e-12)
        assert abs(ours[2] - ref[1]) <= 0.005 * AMPLITUDE[experiment], ours[0]
        for k in (3, 4):
            assert abs(ours[k] - ref[k - 1]) <= 0.005 * p_scale, ours[0]


def test_ssp_package_validates_against_the_ssp_1_0_schemas(ssp):
    ssd_schema = etree.XMLSchema(etree.parse(str(SCHEMA / "SystemStructureDescription.xsd")))
    ssv_schema = etree.XMLSchema(etree.parse(str(SCHEMA / "SystemStructureParameterValues.xsd")))
    with zipfile.ZipFile(ssp) as z:
        names = z.namelist()
        ssd = etree.fromstring(z.read("SystemStructure.ssd"))
        ssd_schema.assertValid(ssd)
        # inline parameter values are `xs:any lax` in the SSD schema: check them as
        # documents of their own schema
        sets = ssd.findall(".//{http://ssp-standard.org/SSP1/SystemStructureParameterValues}ParameterSet")
        assert {s.get("name") for s in sets} >= {"SV1", "Manifold", "Actuator"}
        for s in sets:
            ssv_schema.assertValid(etree.fromstring(etree.tostring(s)))
        for mode in (1, 2, 3):
            ssv_schema.assertValid(etree.fromstring(z.read(f"resources/mode{mode}.ssv")))
        ns = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription"}
        for c in ssd.findall(".//ssd:Component", ns):
            assert c.get("source") in names, c.get("source")
        # the closed-loop variants (SSP 1.0 section 3: further root SSDs, unique names)
        variants = [n for n in names if n.endswith(".ssd") and "/" not in n]
        assert set(variants) == {"SystemStructure.ssd", "ClosedLoop.ssd", "ClosedLoopMode1.ssd",
                                 "ClosedLoopMode2.ssd"}
        roots = [etree.fromstring(z.read(n)) for n in variants]
        assert len({r.get("name") for r in roots}) == len(roots)
        for name, root in zip(variants, roots):
            ssd_schema.assertValid(root)
            for c in root.findall(".//ssd:Component", ns):
                assert c.get("source") in names, (name, c.get("source"))
            if name.startswith("ClosedLoop"):
                to_sv2 = [c for c in root.iter("{%s}Connection" % ns["ssd"])
                          if c.get("endElement") == "SV2" and c.get("endConnector") == "u"]
                # mode 1 holds SV2 at null: nothing drives its command
                assert len(to_sv2) == (0 if name == "ClosedLoopMode1.ssd" else 1), name
