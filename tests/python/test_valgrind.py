"""valgrind (memcheck) over every FMU: a small C host (tools/valgrind/driver.c) runs
instantiate / initialize / step / serialize / deserialize (also into an occupied slot and
a corrupted state) / set state / free cycles over dlopen/dlclose reloads. Asserts no
invalid access and no definitely-lost block. About 8 s per FMU on 2 cores.

Skipped, saying so, when valgrind or a C compiler is absent (tools/setup.sh installs
Debian's valgrind)."""
from __future__ import annotations

import shutil
import subprocess
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import pytest

from conftest import fmu_dir

ROOT = Path(__file__).resolve().parents[2]
RELOADS, CYCLES = 3, 2


def every_fmu() -> list[Path]:
    return sorted(fmu_dir().glob("*.fmu"))


@pytest.fixture(scope="module")
def driver(tmp_path_factory) -> Path:
    if shutil.which("valgrind") is None:
        pytest.skip("valgrind is not installed (bash tools/setup.sh installs it)")
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler to build the valgrind driver")
    exe = tmp_path_factory.mktemp("valgrind") / "driver"
    subprocess.run([cc, "-O1", "-g", "-o", str(exe), str(ROOT / "tools" / "valgrind" / "driver.c"),
                    "-ldl"], check=True)
    return exe


@pytest.mark.parametrize("fmu", every_fmu(), ids=lambda p: p.stem)
def test_no_invalid_access_and_no_leak_under_valgrind(driver, fmu, tmp_path):
    with zipfile.ZipFile(fmu) as z:
        z.extractall(tmp_path)
    md = ET.parse(tmp_path / "modelDescription.xml").getroot()
    ident = md.find("CoSimulation").get("modelIdentifier")
    lib = tmp_path / "binaries" / "linux64" / f"{ident}.so"
    p = subprocess.run(
        ["valgrind", "--error-exitcode=99", "--leak-check=full", "--errors-for-leak-kinds=definite",
         "--show-leak-kinds=definite", "-q", str(driver), str(lib), md.get("guid"),
         (tmp_path / "resources").as_uri(), str(RELOADS), str(CYCLES)],
        capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-4000:]
    assert "Invalid" not in p.stderr and "definitely lost" not in p.stderr, p.stderr[-4000:]
