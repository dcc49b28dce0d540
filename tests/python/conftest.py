"""Fixtures shared by the Python tests of the HydroBench FMUs.

The FMUs are looked for in $HB_FMU_DIR, by default <repo>/target/fmu, where
`bash tools/test.sh` (or `cargo build --release --workspace && ./target/release/hbench fmu
--out target/fmu --force`) puts them.
"""
from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))

import hbfmi  # noqa: E402
from fmpy import extract, read_model_description  # noqa: E402

NAMES = ["servovalve", "manifold", "actuator", "bench", "controller"]


def fmu_dir() -> Path:
    return Path(os.environ.get("HB_FMU_DIR", ROOT / "target" / "fmu")).resolve()


@dataclass
class Unpacked:
    """One FMU file, extracted once per test session."""

    name: str
    path: Path
    dir: Path
    md: object  # fmpy.model_description.ModelDescription

    @property
    def vr(self) -> dict[str, int]:
        return {v.name: v.valueReference for v in self.md.modelVariables}

    @property
    def var(self) -> dict:
        return {v.name: v for v in self.md.modelVariables}

    def names(self, causality: str) -> list[str]:
        return [v.name for v in self.md.modelVariables if v.causality == causality]


@pytest.fixture(scope="session")
def fmu_paths() -> dict[str, Path]:
    d = fmu_dir()
    missing = [n for n in NAMES if not (d / f"{n}.fmu").is_file()]
    if missing:
        pytest.fail(
            f"FMUs {missing} not found in {d} (set HB_FMU_DIR, or build and package them: "
            "`cargo build --release --workspace && ./target/release/hbench fmu --out target/fmu "
            "--force`, which `bash tools/test.sh` does)",
            pytrace=False,
        )
    return {n: d / f"{n}.fmu" for n in NAMES}


@pytest.fixture(scope="session")
def fmus(fmu_paths, tmp_path_factory) -> dict[str, Unpacked]:
    out = {}
    for name, path in fmu_paths.items():
        target = tmp_path_factory.mktemp(name)
        extract(str(path), str(target))
        out[name] = Unpacked(name, path, target, read_model_description(str(target), validate=False))
    return out


@pytest.fixture
def slaves(fmus):
    """Factory of instances, all freed at the end of the test."""
    made: list[hbfmi.Slave] = []

    def make(name: str, **kw) -> hbfmi.Slave:
        s = hbfmi.Slave(fmus[name], **kw)
        made.append(s)
        return s

    yield make
    for s in made:
        s.free()
