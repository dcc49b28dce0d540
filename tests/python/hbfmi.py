"""Raw FMI 2.0 access for the tests: fmpy loads and instantiates, ctypes reads raw statuses.

fmpy raises on any status worse than fmi2Warning and hides the code, so misuse tests call
the C functions themselves through fresh ctypes prototypes (`dll[name]`, not fmpy's own
function objects). Log messages go through fmpy's native logger proxy (it formats the
printf-style message, which ctypes cannot) into one process-wide capture, attributed to
instances by the instance name the FMU passes back.
"""
from __future__ import annotations

import itertools
import math
import struct
from ctypes import (
    byref,
    c_char_p,
    c_double,
    c_int,
    c_size_t,
    c_uint,
    c_void_p,
    create_string_buffer,
)
from dataclasses import dataclass

from fmpy import calloc, free
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)
from fmpy.logging import addLoggerProxy

OK, WARNING, DISCARD, ERROR, FATAL = 0, 1, 2, 3, 4
STATUS = {0: "OK", 1: "Warning", 2: "Discard", 3: "Error", 4: "Fatal", 5: "Pending"}
CO_SIMULATION = 1


@dataclass
class Record:
    env: int | None
    instance: str
    status: int
    category: str
    message: str


LOG: list[Record] = []


def _capture(env, instance, status, category, message):
    dec = lambda b: b.decode("utf-8", "replace") if b is not None else None  # noqa: E731
    LOG.append(Record(env, dec(instance), status, dec(category), dec(message)))


# kept alive for the whole process: the native proxy holds a pointer to it
_CAPTURE = fmi2CallbackLoggerTYPE(_capture)


def callbacks(env: int | None = None, logger: bool = True) -> fmi2CallbackFunctions:
    """A callback struct whose logger lands in LOG (or a NULL logger)."""
    cb = fmi2CallbackFunctions()
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    cb.componentEnvironment = env
    if logger:
        cb.logger = _CAPTURE
        addLoggerProxy(byref(cb))  # (re)points the proxy's target at _CAPTURE
    return cb


_PTR = c_void_p
PROTOTYPES = {
    "fmi2Instantiate": (_PTR, [c_char_p, c_int, c_char_p, c_char_p, _PTR, c_int, c_int]),
    "fmi2FreeInstance": (None, [_PTR]),
    "fmi2SetDebugLogging": (c_int, [_PTR, c_int, c_size_t, _PTR]),
    "fmi2SetupExperiment": (c_int, [_PTR, c_int, c_double, c_double, c_int, c_double]),
    "fmi2EnterInitializationMode": (c_int, [_PTR]),
    "fmi2ExitInitializationMode": (c_int, [_PTR]),
    "fmi2Terminate": (c_int, [_PTR]),
    "fmi2Reset": (c_int, [_PTR]),
    "fmi2GetReal": (c_int, [_PTR, _PTR, c_size_t, _PTR]),
    "fmi2GetInteger": (c_int, [_PTR, _PTR, c_size_t, _PTR]),
    "fmi2GetBoolean": (c_int, [_PTR, _PTR, c_size_t, _PTR]),
    "fmi2SetReal": (c_int, [_PTR, _PTR, c_size_t, _PTR]),
    "fmi2SetInteger": (c_int, [_PTR, _PTR, c_size_t, _PTR]),
    "fmi2SetBoolean": (c_int, [_PTR, _PTR, c_size_t, _PTR]),
    "fmi2DoStep": (c_int, [_PTR, c_double, c_double, c_int]),
    "fmi2GetFMUstate": (c_int, [_PTR, _PTR]),
    "fmi2SetFMUstate": (c_int, [_PTR, _PTR]),
    "fmi2FreeFMUstate": (c_int, [_PTR, _PTR]),
    "fmi2SerializedFMUstateSize": (c_int, [_PTR, _PTR, _PTR]),
    "fmi2SerializeFMUstate": (c_int, [_PTR, _PTR, _PTR, c_size_t]),
    "fmi2DeSerializeFMUstate": (c_int, [_PTR, _PTR, c_size_t, _PTR]),
    "fmi2GetRealStatus": (c_int, [_PTR, c_int, _PTR]),
}


class Raw:
    """The FMI functions of one loaded library with explicit prototypes."""

    def __init__(self, dll):
        for name, (restype, argtypes) in PROTOTYPES.items():
            f = dll[name]
            f.restype = restype
            f.argtypes = argtypes
            setattr(self, name, f)


def vrs(*refs: int):
    return (c_uint * len(refs))(*refs)


def reals(*xs: float):
    return (c_double * len(xs))(*xs)


def bits(x: float) -> bytes:
    """The exact bit pattern of a double, for bit-for-bit comparisons."""
    return struct.pack("<d", x)


_serial = itertools.count()


class Slave:
    """One FMU instance: fmpy for loading, raw calls for anything whose status we check."""

    def __init__(self, unpacked, env: int | None = None, logger: bool = True, logging_on=False):
        self.u = unpacked
        self.name = f"{unpacked.name}#{next(_serial)}"
        self.fmu = FMU2Slave(
            guid=unpacked.md.guid,
            unzipDirectory=str(unpacked.dir),
            modelIdentifier=unpacked.md.coSimulation.modelIdentifier,
            instanceName=self.name,
        )
        self.raw = Raw(self.fmu.dll)
        self.cb = callbacks(env, logger)
        self.fmu.instantiate(callbacks=self.cb, loggingOn=logging_on)
        self.c = self.fmu.component
        self.freed = False

    # --- variables --------------------------------------------------------------
    def vr(self, name: str) -> int:
        return self.u.vr[name]

    def set_reals(self, values: dict[str, float]) -> int:
        names = list(values)
        return self.raw.fmi2SetReal(
            self.c, vrs(*map(self.vr, names)), len(names), reals(*(values[n] for n in names))
        )

    def set_ints(self, values: dict[str, int]) -> int:
        names = list(values)
        arr = (c_int * len(names))(*(values[n] for n in names))
        return self.raw.fmi2SetInteger(self.c, vrs(*map(self.vr, names)), len(names), arr)

    def set_bools(self, values: dict[str, bool]) -> int:
        names = list(values)
        arr = (c_int * len(names))(*(int(values[n]) for n in names))
        return self.raw.fmi2SetBoolean(self.c, vrs(*map(self.vr, names)), len(names), arr)

    def get_reals(self, names) -> list[float]:
        out = reals(*([0.0] * len(names)))
        s = self.raw.fmi2GetReal(self.c, vrs(*map(self.vr, names)), len(names), out)
        assert s == OK, f"{self.name}: fmi2GetReal({names}) -> {STATUS[s]}: {self.messages()}"
        return list(out)

    def get_real(self, name: str) -> float:
        return self.get_reals([name])[0]

    # --- life cycle ---------------------------------------------------------------
    def init(self, start: float = 0.0, reals_: dict | None = None, ints: dict | None = None,
             bools: dict | None = None) -> None:
        for setter, values in ((self.set_reals, reals_), (self.set_ints, ints), (self.set_bools, bools)):
            if values:
                assert setter(values) == OK, self.messages()
        for call, args in (
            ("fmi2SetupExperiment", (0, 0.0, start, 0, 0.0)),
            ("fmi2EnterInitializationMode", ()),
            ("fmi2ExitInitializationMode", ()),
        ):
            s = getattr(self.raw, call)(self.c, *args)
            assert s == OK, f"{self.name}: {call} -> {STATUS[s]}: {self.messages()}"

    def step(self, t: float, h: float) -> int:
        return self.raw.fmi2DoStep(self.c, t, h, 1)

    def free(self) -> None:
        if not self.freed:
            self.raw.fmi2FreeInstance(self.c)
            self.freed = True

    # --- states -------------------------------------------------------------------
    def get_state(self) -> c_void_p:
        st = c_void_p()
        assert self.raw.fmi2GetFMUstate(self.c, byref(st)) == OK, self.messages()
        assert st.value
        return st

    def set_state(self, st) -> int:
        return self.raw.fmi2SetFMUstate(self.c, st)

    def free_state(self, st) -> int:
        return self.raw.fmi2FreeFMUstate(self.c, byref(st))

    def serialize(self, st) -> bytes:
        size = c_size_t()
        assert self.raw.fmi2SerializedFMUstateSize(self.c, st, byref(size)) == OK, self.messages()
        buf = create_string_buffer(size.value)
        assert self.raw.fmi2SerializeFMUstate(self.c, st, buf, size.value) == OK, self.messages()
        return buf.raw

    def deserialize(self, data: bytes) -> tuple[int, c_void_p]:
        st = c_void_p()
        buf = create_string_buffer(data, len(data)) if data else None
        s = self.raw.fmi2DeSerializeFMUstate(self.c, buf, len(data), byref(st))
        return s, st

    # --- log ----------------------------------------------------------------------
    def messages(self, min_status: int = OK) -> list[Record]:
        return [r for r in LOG if r.instance == self.name and r.status >= min_status]

    def mark(self) -> int:
        """Position in the log, to look only at what follows."""
        return len(LOG)

    def since(self, mark: int, min_status: int = OK) -> list[Record]:
        return [r for r in LOG[mark:] if r.instance == self.name and r.status >= min_status]


def finite(xs) -> bool:
    return all(math.isfinite(x) for x in xs)


__all__ = [
    "OK", "WARNING", "DISCARD", "ERROR", "FATAL", "STATUS", "CO_SIMULATION", "LOG", "Record",
    "callbacks", "Raw", "Slave", "vrs", "reals", "bits", "finite", "byref", "c_int", "c_void_p",
]
