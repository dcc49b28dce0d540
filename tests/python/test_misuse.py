"""Every misuse of the FMI API answers with the right status and a log line, and never
crashes the host. Statuses are read raw (ctypes), since fmpy raises on them."""
from __future__ import annotations

import math
from ctypes import addressof, byref, c_char_p, c_double, c_int, c_size_t, c_void_p

import pytest

import hbfmi
from conftest import NAMES
from hbfmi import DISCARD, ERROR, OK, STATUS, reals, vrs

UNKNOWN_VR = 123456


def assert_refused(s, mark, status, expected, *words):
    """status is `expected` (a status or a set of them) and a log line of this instance
    at Discard or worse says so, mentioning each of `words`."""
    allowed = expected if isinstance(expected, (set, tuple)) else {expected}
    assert status in allowed, f"{STATUS.get(status, status)} instead of {[STATUS[e] for e in allowed]}"
    lines = s.since(mark, DISCARD)
    assert lines, f"no log line for a {STATUS[status]} (log: {s.since(mark)})"
    text = " | ".join(r.message for r in lines)
    for w in words:
        assert w in text, f"{w!r} not in the log: {text}"
    assert all(r.category for r in lines)


def first_input(fmus, name):
    return fmus[name].names("input")[0]


# --- value references, causality, state machine -------------------------------------------

@pytest.mark.parametrize("name", NAMES)
def test_unknown_value_reference_is_an_error(slaves, name):
    s = slaves(name)
    s.init()
    for call, arr in (("fmi2GetReal", reals(0.0)), ("fmi2SetReal", reals(1.0)),
                      ("fmi2GetInteger", (c_int * 1)()), ("fmi2SetBoolean", (c_int * 1)(1))):
        mark = s.mark()
        st = getattr(s.raw, call)(s.c, vrs(UNKNOWN_VR), 1, arr)
        assert_refused(s, mark, st, ERROR, str(UNKNOWN_VR))


def test_wrong_base_type_is_an_error(slaves):
    s = slaves("bench")
    s.init()
    mark = s.mark()
    st = s.raw.fmi2GetInteger(s.c, vrs(s.vr("y")), 1, (c_int * 1)())
    assert_refused(s, mark, st, ERROR, "y")
    mark = s.mark()
    st = s.raw.fmi2SetReal(s.c, vrs(s.vr("mode")), 1, reals(2.0))
    assert_refused(s, mark, st, ERROR, "mode")


@pytest.mark.parametrize("name", NAMES)
def test_setting_an_output_is_an_error(slaves, fmus, name):
    s = slaves(name)
    out = fmus[name].names("output")[0]
    mark = s.mark()
    assert_refused(s, mark, s.set_reals({out: 0.0}), ERROR, out)
    s2 = slaves(name)
    s2.init()
    mark = s2.mark()
    assert_refused(s2, mark, s2.set_reals({out: 0.0}), ERROR, out)


def test_setting_a_parameter_after_initialization_is_an_error(slaves):
    s = slaves("bench")
    assert s.set_reals({"P_supply": 200e5}) == OK  # instantiated: allowed
    s.raw.fmi2SetupExperiment(s.c, 0, 0.0, 0.0, 0, 0.0)
    assert s.raw.fmi2EnterInitializationMode(s.c) == OK
    assert s.set_reals({"P_supply": 190e5}) == OK  # initialization mode: allowed
    assert s.raw.fmi2ExitInitializationMode(s.c) == OK
    mark = s.mark()
    assert_refused(s, mark, s.set_reals({"P_supply": 150e5}), ERROR, "P_supply")
    mark = s.mark()
    assert_refused(s, mark, s.set_bools({"effect.payload": True}), ERROR, "effect.payload")
    assert s.get_real("P_supply") == 190e5


def test_do_step_before_initialization_is_an_error(slaves):
    s = slaves("bench")
    mark = s.mark()
    assert_refused(s, mark, s.step(0.0, 1e-3), ERROR, "fmi2DoStep")
    s2 = slaves("bench")
    s2.raw.fmi2SetupExperiment(s2.c, 0, 0.0, 0.0, 0, 0.0)
    assert s2.raw.fmi2EnterInitializationMode(s2.c) == OK
    mark = s2.mark()
    assert_refused(s2, mark, s2.step(0.0, 1e-3), ERROR, "fmi2DoStep")


@pytest.mark.parametrize("name", NAMES)
def test_do_step_at_the_wrong_time_is_an_error(slaves, name):
    s = slaves(name)
    s.init()
    assert s.step(0.0, 1e-3) == OK
    mark = s.mark()
    assert_refused(s, mark, s.step(0.5, 1e-3), ERROR)
    s2 = slaves(name)
    s2.init(start=1.0)
    mark = s2.mark()
    assert_refused(s2, mark, s2.step(0.0, 1e-3), ERROR)


@pytest.mark.parametrize("h", [0.0, -1e-3, math.nan, math.inf])
def test_do_step_with_a_non_positive_or_non_finite_size_is_an_error(slaves, h):
    s = slaves("bench")
    s.init()
    mark = s.mark()
    assert_refused(s, mark, s.step(0.0, h), ERROR)


def test_calls_in_the_wrong_state_are_errors(slaves):
    cases = [
        ("fmi2ExitInitializationMode", ()),
        ("fmi2Terminate", ()),
    ]
    for call, args in cases:
        s = slaves("actuator")
        mark = s.mark()
        assert_refused(s, mark, getattr(s.raw, call)(s.c, *args), ERROR, call)
    s = slaves("actuator")
    s.init()
    mark = s.mark()
    st = s.raw.fmi2SetupExperiment(s.c, 0, 0.0, 0.0, 0, 0.0)
    assert_refused(s, mark, st, ERROR, "fmi2SetupExperiment")
    s = slaves("actuator")
    s.init()
    mark = s.mark()
    assert_refused(s, mark, s.raw.fmi2EnterInitializationMode(s.c), ERROR)
    # outputs have no value before initialization mode
    s = slaves("actuator")
    mark = s.mark()
    out = (c_double * 1)()
    assert_refused(s, mark, s.raw.fmi2GetReal(s.c, vrs(s.vr("y")), 1, out), ERROR, "y")


def test_reset_after_an_error_gives_a_usable_instance(slaves):
    s = slaves("bench")
    assert s.step(0.0, 1e-3) == ERROR  # not initialized
    assert s.raw.fmi2Reset(s.c) == OK
    s.init()
    assert s.step(0.0, 1e-3) == OK
    assert s.raw.fmi2Terminate(s.c) == OK
    assert s.raw.fmi2Reset(s.c) == OK
    s.init(start=2.0)
    assert s.step(2.0, 1e-3) == OK


# --- values --------------------------------------------------------------------------------

@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("name", NAMES)
def test_non_finite_input_is_discarded_with_a_message(slaves, fmus, name, bad):
    n = first_input(fmus, name)
    s = slaves(name)
    s.init()
    before = s.get_real(n)
    mark = s.mark()
    assert_refused(s, mark, s.set_reals({n: bad}), DISCARD, n)
    assert s.get_real(n) == before, "the refused value was taken"
    assert s.step(0.0, 1e-3) == OK, s.messages()  # the instance goes on
    assert hbfmi.finite(s.get_reals(fmus[name].names("output")))


def test_non_finite_input_before_initialization_is_discarded(slaves):
    s = slaves("bench")
    mark = s.mark()
    assert_refused(s, mark, s.set_reals({"u1": math.nan}), DISCARD, "u1")


def test_tank_above_supply_is_an_error_at_initialization(slaves):
    s = slaves("bench")
    # each within its own bounds (P_supply >= 10 bar, P_tank <= 20 bar)
    assert s.set_reals({"P_supply": 10e5, "P_tank": 15e5}) == OK, s.messages()
    s.raw.fmi2SetupExperiment(s.c, 0, 0.0, 0.0, 0, 0.0)
    mark = s.mark()
    assert_refused(s, mark, s.raw.fmi2EnterInitializationMode(s.c), ERROR, "tank")
    # and no step is taken with it
    assert s.step(0.0, 1e-3) == ERROR


@pytest.mark.parametrize("name,var,bad", [
    ("bench", "fluid.bulk_modulus", 1e12),
    ("bench", "fluid.bulk_modulus", -1.7e9),
    ("bench", "P_supply", math.nan),
    ("bench", "payload_mass", -10.0),
    ("actuator", "fluid.bulk_modulus", 1e12),
    ("manifold", "fluid.bulk_modulus", 1e12),
    ("controller", "Kp", -1.0),
])
def test_out_of_bounds_parameter_is_refused_on_set(slaves, name, var, bad):
    s = slaves(name)
    before = s.get_real(var)
    mark = s.mark()
    assert_refused(s, mark, s.set_reals({var: bad}), {DISCARD, ERROR}, var)
    assert s.get_real(var) == before


@pytest.mark.parametrize("name", ["bench", "manifold"])
def test_mode_out_of_range_is_refused(slaves, name):
    s = slaves(name)
    for bad in (0, 4, -1):
        mark = s.mark()
        assert_refused(s, mark, s.set_ints({"mode": bad}), {DISCARD, ERROR}, "mode")
    out = (c_int * 1)()
    assert s.raw.fmi2GetInteger(s.c, vrs(s.vr("mode")), 1, out) == OK
    assert out[0] == 3


def test_controller_law_outside_the_enumeration_is_refused(slaves):
    s = slaves("controller")
    mark = s.mark()
    assert_refused(s, mark, s.set_ints({"law": 99}), {DISCARD, ERROR}, "law")


# --- instantiation -------------------------------------------------------------------------

def instantiate(s, guid=None, fmu_type=hbfmi.CO_SIMULATION, instance=b"raw", cb=None):
    """Raw fmi2Instantiate through the library that instance `s` loaded."""
    return s.raw.fmi2Instantiate(
        instance, fmu_type, s.u.md.guid.encode() if guid is None else guid,
        (s.u.dir / "resources").as_uri().encode(),
        byref(cb) if cb is not None else None, 0, 0)


@pytest.fixture
def lib(slaves):
    """A bench instance, whose library the raw instantiations use."""
    return slaves("bench")


def test_wrong_guid_gives_null_and_a_message(lib):
    env = c_int(7)
    cb = hbfmi.callbacks(env=addressof(env))
    mark = len(hbfmi.LOG)
    name = b"wrong-guid"
    c = instantiate(lib, guid=b"{00000000-0000-0000-0000-000000000000}", instance=name,
                    cb=cb)
    assert c is None
    lines = [r for r in hbfmi.LOG[mark:] if r.instance == name.decode()]
    assert lines and lines[0].status == ERROR, hbfmi.LOG[mark:]
    assert "GUID" in lines[0].message
    assert lines[0].env == addressof(env)


@pytest.mark.parametrize("case", ["model exchange", "null name", "empty name", "null guid"])
def test_bad_instantiate_arguments_give_null(lib, case):
    cb = hbfmi.callbacks()
    mark = len(hbfmi.LOG)
    kw = {
        "model exchange": dict(fmu_type=0),
        "null name": dict(instance=None),
        "empty name": dict(instance=b""),
        "null guid": dict(guid=None),
    }[case]
    if case == "null guid":
        c = lib.raw.fmi2Instantiate(b"g", 1, None, None, byref(cb), 0, 0)
    else:
        c = instantiate(lib, cb=cb, **kw)
    assert c is None
    assert [r for r in hbfmi.LOG[mark:] if r.status >= ERROR], "no message"


def test_null_logger_in_the_callbacks_does_not_crash(slaves):
    s = slaves("bench", logger=False)
    s.init()
    mark = len(hbfmi.LOG)
    assert s.set_reals({"u1": math.nan}) == DISCARD
    assert s.raw.fmi2GetReal(s.c, vrs(UNKNOWN_VR), 1, reals(0.0)) == ERROR
    assert s.step(3.0, 1e-3) == ERROR
    assert len(hbfmi.LOG) == mark
    cb = hbfmi.callbacks(logger=False)
    assert instantiate(s, guid=b"{nope}", cb=cb) is None
    # no callback struct at all: a NULL instance or a working one, but no crash
    c = instantiate(s, cb=None)
    if c is not None:
        assert s.raw.fmi2GetReal(c, vrs(UNKNOWN_VR), 1, reals(0.0)) == ERROR
        s.raw.fmi2FreeInstance(c)


# --- null pointers -------------------------------------------------------------------------

def test_null_arrays_are_errors(slaves):
    s = slaves("bench")
    s.init()
    for call, args in (
        ("fmi2GetReal", (None, 2, reals(0.0, 0.0))),
        ("fmi2GetReal", (vrs(3, 4), 2, None)),
        ("fmi2SetReal", (None, 1, reals(1.0))),
        ("fmi2SetReal", (vrs(0), 1, None)),
        ("fmi2SetInteger", (None, 1, (c_int * 1)(1))),
        ("fmi2GetBoolean", (vrs(17), 1, None)),
    ):
        mark = s.mark()
        assert_refused(s, mark, getattr(s.raw, call)(s.c, *args), ERROR, "NULL")
    # n = 0 with NULL arrays is a valid empty call
    assert s.raw.fmi2GetReal(s.c, None, 0, None) == OK


def test_null_state_pointers_are_errors(slaves):
    s = slaves("bench")
    s.init()
    size = c_size_t()
    st = s.get_state()
    buf = (c_void_p * 4)()
    for call, args in (
        ("fmi2GetFMUstate", (None,)),
        ("fmi2SetFMUstate", (None,)),
        ("fmi2SerializedFMUstateSize", (None, byref(size))),
        ("fmi2SerializedFMUstateSize", (st, None)),
        ("fmi2SerializeFMUstate", (None, buf, 32)),
        ("fmi2SerializeFMUstate", (st, None, 32)),
        ("fmi2DeSerializeFMUstate", (None, 10, byref(c_void_p()))),
        ("fmi2DeSerializeFMUstate", (buf, 32, None)),
    ):
        mark = s.mark()
        assert_refused(s, mark, getattr(s.raw, call)(s.c, *args), ERROR)
    # a too small buffer for the serialized state
    mark = s.mark()
    assert_refused(s, mark, s.raw.fmi2SerializeFMUstate(s.c, st, buf, 4), ERROR)
    # freeing a NULL state is harmless
    assert s.raw.fmi2FreeFMUstate(s.c, None) == OK
    assert s.free_state(st) == OK


def test_set_debug_logging_null_category_is_an_error(slaves):
    s = slaves("bench")
    cats = (c_char_p * 2)(b"logEvents", None)
    mark = s.mark()
    assert_refused(s, mark, s.raw.fmi2SetDebugLogging(s.c, 1, 2, cats), ERROR, "NULL")
    mark = s.mark()
    assert_refused(s, mark, s.raw.fmi2SetDebugLogging(s.c, 1, 1, None), ERROR, "NULL")
    mark = s.mark()
    unknown = (c_char_p * 1)(b"logNoSuchThing")
    assert_refused(s, mark, s.raw.fmi2SetDebugLogging(s.c, 1, 1, unknown), ERROR,
                   "logNoSuchThing")
    good = (c_char_p * 1)(b"logEvents")
    assert s.raw.fmi2SetDebugLogging(s.c, 1, 1, good) == OK


def test_debug_logging_categories_switch_event_messages(slaves):
    on = slaves("bench", logging_on=True)
    on.init()
    assert [r for r in on.messages() if r.category == "logEvents"], on.messages()
    off = slaves("bench", logging_on=False)
    off.init()
    assert off.messages() == []
    quiet = slaves("bench", logging_on=True)
    assert quiet.raw.fmi2SetDebugLogging(quiet.c, 0, 0, None) == OK  # all categories off
    quiet.init()
    assert quiet.messages() == []


def test_null_and_foreign_component_pointers_are_errors(slaves):
    s = slaves("bench")
    junk = (c_double * 64)()
    for c in (None, addressof(junk)):
        assert s.raw.fmi2DoStep(c, 0.0, 1e-3, 1) == ERROR
        assert s.raw.fmi2GetReal(c, vrs(3), 1, reals(0.0)) == ERROR
        assert s.raw.fmi2EnterInitializationMode(c) == ERROR
        assert s.raw.fmi2SetDebugLogging(c, 1, 0, None) == ERROR
    s.raw.fmi2FreeInstance(None)
    s.raw.fmi2FreeInstance(addressof(junk))
    assert list(junk) == [0.0] * 64


def test_free_twice_and_calls_after_free_do_not_crash(slaves):
    s = slaves("bench")
    s.init()
    assert s.step(0.0, 1e-3) == OK
    keep = slaves("bench")  # keeps the library loaded and shows the others are untouched
    keep.init()
    s.free()
    s.raw.fmi2FreeInstance(s.c)  # twice
    assert s.raw.fmi2DoStep(s.c, 1e-3, 1e-3, 1) == ERROR
    assert s.raw.fmi2GetReal(s.c, vrs(3), 1, reals(0.0)) == ERROR
    assert s.raw.fmi2SetReal(s.c, vrs(0), 1, reals(1.0)) == ERROR
    assert s.raw.fmi2Terminate(s.c) == ERROR
    assert s.raw.fmi2Reset(s.c) == ERROR
    assert s.raw.fmi2GetFMUstate(s.c, byref(c_void_p())) == ERROR
    assert keep.step(0.0, 1e-3) == OK


# --- logger --------------------------------------------------------------------------------

@pytest.mark.parametrize("name", NAMES)
def test_logger_gets_the_component_environment_back(slaves, fmus, name):
    env = (c_double * 1)(42.0)
    s = slaves(name, env=addressof(env), logging_on=True)
    s.init()
    s.set_reals({first_input(fmus, name): math.inf})
    s.raw.fmi2GetReal(s.c, vrs(UNKNOWN_VR), 1, reals(0.0))
    lines = s.messages()
    assert len(lines) >= 2
    assert {r.env for r in lines} == {addressof(env)}
    assert env[0] == 42.0
    other = slaves(name)  # an instance without environment gets NULL back
    other.raw.fmi2GetReal(other.c, vrs(UNKNOWN_VR), 1, reals(0.0))
    assert {r.env for r in other.messages()} == {None}


def test_messages_with_format_characters_arrive_verbatim(slaves):
    s = slaves("controller")
    cats = (c_char_p * 1)(b"log%s%n%d")
    mark = s.mark()
    st = s.raw.fmi2SetDebugLogging(s.c, 1, 1, cats)
    assert_refused(s, mark, st, ERROR, "log%s%n%d")
