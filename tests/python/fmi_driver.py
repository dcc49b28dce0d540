"""Memory probes for test_defects.py, each run in a fresh process so that its resident
set is the library's alone: prints one JSON line with the RSS growth (kB).

    fmi_driver.py reload DIR N       dlopen, instantiate, free, dlclose N times
    fmi_driver.py deserialize DIR N  deserialize a state N times into one slot

DIR is an extracted FMU. Plain ctypes, no fmpy: fmpy keeps its own references to the
library, which would keep it loaded.
"""
from __future__ import annotations

import _ctypes
import json
import os
import sys
import xml.etree.ElementTree as ET
from ctypes import CDLL, RTLD_LOCAL, byref, c_char_p, c_double, c_int, c_size_t, c_void_p, create_string_buffer
from pathlib import Path

PAGE_KB = os.sysconf("SC_PAGE_SIZE") // 1024
WARM_UP = 10


def rss_kb() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * PAGE_KB


def fmu_facts(d: Path) -> tuple[Path, bytes, bytes]:
    md = ET.parse(d / "modelDescription.xml").getroot()
    ident = md.find("CoSimulation").get("modelIdentifier")
    return (d / "binaries" / "linux64" / f"{ident}.so", md.get("guid").encode(),
            (d / "resources").as_uri().encode())


def load(lib: Path):
    dll = CDLL(str(lib), mode=RTLD_LOCAL)
    dll.fmi2Instantiate.restype = c_void_p
    dll.fmi2Instantiate.argtypes = [c_char_p, c_int, c_char_p, c_char_p, c_void_p, c_int, c_int]
    dll.fmi2FreeInstance.argtypes = [c_void_p]
    for name in ("fmi2SetupExperiment", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode",
                 "fmi2GetFMUstate", "fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate",
                 "fmi2DeSerializeFMUstate", "fmi2FreeFMUstate"):
        getattr(dll, name).restype = c_int
    dll.fmi2SetupExperiment.argtypes = [c_void_p, c_int, c_double, c_double, c_int, c_double]
    return dll


def reload(d: Path, n: int) -> dict:
    lib, guid, res = fmu_facts(d)
    before = None
    for i in range(n + WARM_UP):
        if i == WARM_UP:
            before = rss_kb()
        dll = load(lib)
        c = dll.fmi2Instantiate(b"reload", 1, guid, res, None, 0, 0)
        assert c, "instantiation failed"
        dll.fmi2FreeInstance(c)
        _ctypes.dlclose(dll._handle)
        del dll
    return {"reloads": n, "growth_kb": rss_kb() - before}


def deserialize(d: Path, n: int) -> dict:
    lib, guid, res = fmu_facts(d)
    dll = load(lib)
    c = c_void_p(dll.fmi2Instantiate(b"deser", 1, guid, res, None, 0, 0))
    for call, args in (("fmi2SetupExperiment", (0, 0.0, 0.0, 0, 0.0)),
                       ("fmi2EnterInitializationMode", ()), ("fmi2ExitInitializationMode", ())):
        assert getattr(dll, call)(c, *args) == 0, call
    st, size = c_void_p(), c_size_t()
    assert dll.fmi2GetFMUstate(c, byref(st)) == 0
    assert dll.fmi2SerializedFMUstateSize(c, st, byref(size)) == 0
    buf = create_string_buffer(size.value)
    assert dll.fmi2SerializeFMUstate(c, st, buf, size) == 0
    slot = c_void_p()
    before = None
    for i in range(n + WARM_UP * 100):
        if i == WARM_UP * 100:
            before = rss_kb()
        assert dll.fmi2DeSerializeFMUstate(c, buf, size, byref(slot)) == 0
    growth = rss_kb() - before
    dll.fmi2FreeFMUstate(c, byref(slot))
    dll.fmi2FreeFMUstate(c, byref(st))
    dll.fmi2FreeInstance(c)
    return {"deserializations": n, "growth_kb": growth}


if __name__ == "__main__":
    mode, d, n = sys.argv[1], Path(sys.argv[2]), int(sys.argv[3])
    print(json.dumps({"reload": reload, "deserialize": deserialize}[mode](d, n)))
