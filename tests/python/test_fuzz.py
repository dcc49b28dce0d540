"""A bounded run of our own FMI fuzzer (tools/fuzz/fuzz.py) on every FMU in the FMU
directory: no crash, no hang, no fmi2OK with a non-finite output, no refusal without a
message, the same sequence giving the same results twice. About 90 s of wall time; the
long run and its figures are in docs/fuzz.md."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from conftest import fmu_dir

ROOT = Path(__file__).resolve().parents[2]
FUZZ_SECONDS = 80


def test_fuzzer_finds_nothing_on_every_fmu():
    out = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "fuzz" / "fuzz.py"), "--fmu-dir", str(fmu_dir()),
         "--seconds", str(FUZZ_SECONDS), "--seed", "16", "--batch", "2", "--calls", "40",
         "--timeout", "60"],
        capture_output=True, text=True, timeout=FUZZ_SECONDS + 240, check=True)
    r = json.loads(out.stdout)
    assert len(r["fmus"]) >= 6, r["fmus"]
    assert r["sequences"] > 50 and r["steps_ok"] > 100, r  # the run reached running instances
    for key in ("crashes", "hangs", "non_finite_ok", "nondeterministic", "other_violations"):
        assert r[key] == 0, (key, r["findings"])
