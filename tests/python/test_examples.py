"""The fmpy examples in tools/fmpy run as a user runs them, without matplotlib."""
from __future__ import annotations

import csv
import re
import subprocess
import sys

import pytest

from conftest import ROOT, fmu_dir

TOOLS = ROOT / "tools" / "fmpy"

# run a script as __main__ with matplotlib made unimportable
NO_MATPLOTLIB = (
    "import runpy, sys; sys.modules['matplotlib'] = None; "
    "sys.argv = sys.argv[1:]; runpy.run_path(sys.argv[0], run_name='__main__')"
)


def run_example(args, tmp_path):
    p = subprocess.run([sys.executable, "-c", NO_MATPLOTLIB, *map(str, args)], cwd=tmp_path,
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stdout + p.stderr
    return p.stdout


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], [[float(x) for x in r] for r in rows[1:]]


@pytest.fixture(scope="module")
def step_runs(fmu_paths, tmp_path_factory):
    out = {}
    for ctl in ("fmu", "python"):
        d = tmp_path_factory.mktemp(f"step-{ctl}")
        stdout = run_example([TOOLS / "simulate_bench.py", "--fmu-dir", fmu_dir(), "--out", d,
                              "--controller", ctl], d)
        out[ctl] = (d, stdout)
    return out


def test_simulate_bench_writes_a_csv_and_no_png_without_matplotlib(step_runs):
    d, stdout = step_runs["fmu"]
    assert "bench_step.csv" in stdout
    assert not (d / "bench_step.png").exists()
    header, rows = read_csv(d / "bench_step.csv")
    assert header == ["time", "y_ref", "y", "v", "P1", "P2", "u1", "u2"]
    col = {n: [r[k] for r in rows] for k, n in enumerate(header)}
    assert len(rows) == 201 and col["time"][-1] == pytest.approx(0.2)
    assert all(dt == pytest.approx(1e-3) for dt in
               (b - a for a, b in zip(col["time"], col["time"][1:])))
    # the step: 10 mm from t = 10 ms, reached without overshoot beyond 5 %
    assert col["y_ref"][0] == 0.0 and col["y_ref"][-1] == 0.010
    assert col["y"][-1] == pytest.approx(0.010, abs=0.1e-3)
    assert max(col["y"]) < 0.0105
    # the controller's law on the exchanged values
    for y_ref, y, u1, u2 in zip(col["y_ref"], col["y"], col["u1"], col["u2"]):
        assert u1 == pytest.approx(min(max(1169.0 * (y_ref - y), -10.0), 10.0), abs=1e-9)
        assert u2 == -u1
    assert max(col["u1"]) == 10.0  # saturated right after the step
    # 95 % rise time near the thesis's mode-3 figure (README: 0.051 s simulated, 0.055 s bench)
    t95 = next(t for t, y in zip(col["time"], col["y"]) if t >= 0.01 and y >= 0.0095) - 0.01
    assert 0.025 < t95 < 0.08
    assert re.search(r"rise time \d+ ms", stdout)


def test_python_controller_gives_the_same_loop_as_controller_fmu(step_runs):
    a = (step_runs["fmu"][0] / "bench_step.csv").read_text()
    b = (step_runs["python"][0] / "bench_step.csv").read_text()
    assert a == b


def readme_snippets():
    text = (TOOLS / "README.md").read_text()
    return re.findall(r"```python\n(.*?)```", text, re.S)


def test_readme_has_one_snippet_per_fmu():
    snippets = readme_snippets()
    for name in ("servovalve", "manifold", "actuator", "bench", "controller"):
        assert sum(f"target/fmu/{name}.fmu" in s for s in snippets) == 1, name


# what each snippet prints first, as the README's comments say
EXPECT = {
    "servovalve": (19.0, 0.03),  # L/min
    "actuator": (1e-4 / 9.456e-4, 0.05),  # m/s
    "controller": (1169.0 * 0.003, 1e-9),  # V
}


@pytest.mark.parametrize("k", range(5))
def test_readme_snippet_runs(fmu_paths, tmp_path, k):
    code = readme_snippets()[k]
    name = re.search(r"target/fmu/(\w+)\.fmu", code).group(1)
    script = tmp_path / "snippet.py"
    script.write_text(code.replace('"target/fmu/', f'"{fmu_dir()}/'))
    out = run_example([script], tmp_path)
    numbers = [float(x) for x in re.findall(r"-?\d+\.?\d*(?:e-?\d+)?", out)]
    assert numbers, out
    if name in EXPECT:
        value, rel = EXPECT[name]
        assert numbers[0] == pytest.approx(value, rel=rel), out
