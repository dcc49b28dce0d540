"""Parameters come from the FMU's resources/parameters.toml when it ships one."""
from __future__ import annotations

import shutil

import pytest

import hbfmi
from conftest import Unpacked
from hbfmi import ERROR, OK


def with_parameters(fmus, tmp_path, name, text):
    """A copy of the extracted FMU whose resources hold `text` as parameters.toml."""
    u = fmus[name]
    d = tmp_path / name
    shutil.copytree(u.dir, d)
    (d / "resources").mkdir(exist_ok=True)
    (d / "resources" / "parameters.toml").write_text(text)
    return Unpacked(name, u.path, d, u.md)


def test_bench_reads_its_parameter_file(fmus, tmp_path):
    u = with_parameters(fmus, tmp_path, "bench",
                        'mode = 1\nsupply_pressure = 15e6\n[effects]\npayload = true\n')
    s = hbfmi.Slave(u)
    try:
        assert s.get_real("P_supply") == 15e6
        flag = (hbfmi.c_int * 1)()
        assert s.raw.fmi2GetBoolean(s.c, hbfmi.vrs(s.vr("effect.payload")), 1, flag) == OK
        assert flag[0] == 1
        assert s.raw.fmi2GetInteger(s.c, hbfmi.vrs(s.vr("mode")), 1, flag) == OK
        assert flag[0] == 1
        s.init()
        assert s.step(0.0, 1e-3) == OK
    finally:
        s.free()
    # the shipped FMU, without the file, keeps its built-in values
    plain = hbfmi.Slave(fmus["bench"])
    try:
        assert plain.get_real("P_supply") == float(fmus["bench"].var["P_supply"].start)
    finally:
        plain.free()


@pytest.mark.parametrize("text,words", [
    ("supply_pressure = \"high\"\n", ["parameters.toml:1"]),
    ("[effects]\nno_such_effect = true\n", ["parameters.toml:2", "no_such_effect"]),
    ("tank_pressure = 30e6\n", ["parameters.toml:1", "tank_pressure"]),
])
def test_a_bad_parameter_file_refuses_instantiation_with_a_message(fmus, tmp_path, text, words):
    u = with_parameters(fmus, tmp_path, "bench", text)
    first = hbfmi.Slave(fmus["bench"])  # loads the library
    try:
        cb = hbfmi.callbacks()
        mark = len(hbfmi.LOG)
        c = first.raw.fmi2Instantiate(b"badfile", hbfmi.CO_SIMULATION, u.md.guid.encode(),
                                      (u.dir / "resources").as_uri().encode(),
                                      hbfmi.byref(cb), 0, 0)
        assert c is None
        lines = [r for r in hbfmi.LOG[mark:] if r.instance == "badfile" and r.status >= ERROR]
        assert lines, hbfmi.LOG[mark:]
        for w in words:
            assert w in lines[0].message, lines[0].message
    finally:
        first.free()
