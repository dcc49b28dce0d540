"""The bench as a system of FMUs (issue 7): the component FMUs wired by bench.ssp and
co-simulated by `hbench cosim` match bench.fmu; the fmpy master (tools/fmpy/cosim.py)
agrees with `hbench cosim`; the SSP package validates against the SSP 1.0 XSDs.

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


@pytest.fixture(scope="module")
def hbench_run(ssp, tmp_path_factory):
    """`hbench cosim` at 0.1 ms, Gauss-Seidel, every mode and experiment."""
    out = tmp_path_factory.mktemp("cosim")
    exe = ROOT / "target" / "release" / "hbench"
    subprocess.run([str(exe), "cosim", "--system", str(ssp), "--bench", str(ssp.parent / "bench.fmu"),
                    "--order", "gauss-seidel", "--steps", str(STEP), "--out", str(out)],
                   check=True, capture_output=True, text=True)
    runs = json.loads((out / "cosim_errors.json").read_text())["runs"]
    traces = {}
    with open(out / "cosim_traces.csv", newline="") as f:
        for r in csv.DictReader(f):
            key = (r["experiment"], int(r["mode"]), r["order"])
            traces.setdefault(key, []).append([float(r[c]) for c in ("time", "y", "P1", "P2")])
    return out, runs, traces


def test_components_match_bench_fmu_at_a_tenth_of_a_millisecond(hbench_run):
    _, runs, _ = hbench_run
    assert len(runs) == 6
    for r in runs:
        what = f"{r['experiment']} mode {r['mode']}"
        assert r["stable"], f"{what}: {r['failure']}"
        assert r["position_error_percent"] < 2.0, what
        assert r["pressure_error_bar"] < 5.0, what


@pytest.mark.parametrize("experiment,mode", [("move", 1), ("move", 3), ("sine", 2)])
def test_fmpy_master_agrees_with_hbench(hbench_run, ssp, experiment, mode):
    out, _, traces = hbench_run
    reference = cosim.read_reference(out / f"reference_{experiment}.csv")
    rows = cosim.simulate(ssp, reference, mode=mode, step=STEP, order="gauss-seidel")
    theirs = traces[(experiment, mode, "gauss-seidel")]
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
        assert {s.get("name") for s in sets} >= {"sv1", "manifold", "actuator"}
        for s in sets:
            ssv_schema.assertValid(etree.fromstring(etree.tostring(s)))
        for mode in (1, 2, 3):
            ssv_schema.assertValid(etree.fromstring(z.read(f"resources/mode{mode}.ssv")))
        ns = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription"}
        for c in ssd.findall(".//ssd:Component", ns):
            assert c.get("source") in names, c.get("source")
