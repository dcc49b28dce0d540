"""FMU state: get/set and serialize/deserialize roll back bit for bit; instances are
independent of each other."""
from __future__ import annotations

import math
import struct
from ctypes import byref

import pytest

from conftest import NAMES
from hbfmi import ERROR, OK, STATUS, bits

H = 1e-3
OUTPUTS = ["y", "v", "a", "P1", "P2", "P_A1", "P_B1", "P_A2", "P_B2", "Q1", "Q2"]

# inputs that make each FMU evolve, as a function of time
DRIVE = {
    "servovalve": lambda t: {"u": 3.0 + 4.0 * math.sin(300 * t), "P_A": 120e5, "P_B": 60e5},
    "manifold": lambda t: {"Q_A1": 1e-4 * math.sin(200 * t), "Q_B2": -5e-5, "P1": 110e5, "P2": 100e5},
    "actuator": lambda t: {"Q1": 1e-4 * math.cos(100 * t), "Q2": -1e-4 * math.cos(100 * t)},
    "bench": lambda t: {"u1": 2.0 * math.sin(150 * t), "u2": -2.0 * math.sin(150 * t)},
    "controller": lambda t: {"y_ref": 0.005 * math.sin(100 * t), "y": 0.001},
}


def run(s, t0, n, drive, outputs):
    """n steps of H from t0, inputs from drive(t) at each communication point; the exact bits
    of every output after every step."""
    rec = []
    for k in range(n):
        t = t0 + k * H
        assert s.set_reals(drive(t)) == OK, s.messages()
        st = s.step(t, H)
        assert st == OK, f"doStep at {t}: {STATUS[st]} {s.messages()}"
        rec.append([bits(x) for x in s.get_reals(outputs)])
    return rec


def same(got, want, outputs):
    """True, or an AssertionError naming the first output that differs and by how much."""
    for k, (g, w) in enumerate(zip(got, want)):
        for n, gb, wb in zip(outputs, g, w):
            if gb != wb:
                gx, wx = (struct.unpack("<d", b)[0] for b in (gb, wb))
                ulps = abs(struct.unpack("<q", gb)[0] - struct.unpack("<q", wb)[0])
                raise AssertionError(f"step {k + 1}: {n} = {gx!r} instead of {wx!r} ({ulps} ulp)")
    assert len(got) == len(want)
    return True


def advance(s, drive, n):
    run(s, 0.0, n, drive, [])


@pytest.fixture
def bench(slaves):
    s = slaves("bench")
    s.init()
    advance(s, DRIVE["bench"], 20)  # t = 0.02
    return s


def test_get_set_state_replays_bench_bit_for_bit(bench):
    drive = DRIVE["bench"]
    state = bench.get_state()
    first = run(bench, 0.02, 20, drive, OUTPUTS)
    assert bench.set_state(state) == OK, bench.messages()
    assert same(run(bench, 0.02, 20, drive, OUTPUTS), first, OUTPUTS)
    # a rollback really goes back: the outputs at 0.04 differ from those at 0.02
    assert first[0] != first[-1]
    # the slot can be reused (updated in place), then freed
    assert bench.raw.fmi2GetFMUstate(bench.c, byref(state)) == OK
    assert bench.free_state(state) == OK
    assert state.value is None


def test_serialized_state_replays_bench_in_the_same_and_a_fresh_instance(bench, slaves):
    drive = DRIVE["bench"]
    data = bench.serialize(bench.get_state())
    assert len(data) > 16
    first = run(bench, 0.02, 20, drive, OUTPUTS)

    status, restored = bench.deserialize(data)
    assert status == OK, bench.messages()
    assert bench.set_state(restored) == OK, bench.messages()
    assert same(run(bench, 0.02, 20, drive, OUTPUTS), first, OUTPUTS)

    fresh = slaves("bench")  # only instantiated: the state brings time and parameters
    status, restored = fresh.deserialize(data)
    assert status == OK, fresh.messages()
    assert fresh.set_state(restored) == OK, fresh.messages()
    assert same(run(fresh, 0.02, 20, drive, OUTPUTS), first, OUTPUTS)
    # the serialization of a restored state is the same byte string
    assert fresh.serialize(restored) == data


@pytest.mark.parametrize("name", NAMES)
def test_serialize_roundtrip_every_fmu(slaves, fmus, name):
    drive, outputs = DRIVE[name], fmus[name].names("output")
    a = slaves(name)
    a.init()
    advance(a, drive, 5)
    data = a.serialize(a.get_state())
    first = run(a, 0.005, 10, drive, outputs)
    b = slaves(name)
    status, st = b.deserialize(data)
    assert status == OK, b.messages()
    assert b.set_state(st) == OK, b.messages()
    assert same(run(b, 0.005, 10, drive, outputs), first, outputs)


def garbage_cases(valid: bytes, foreign: bytes):
    flipped = bytearray(valid)
    flipped[-3] ^= 0x01
    return {
        "random": bytes(range(7, 250, 3)) * 3,
        "empty-ish": b"\x00",
        "truncated": valid[: len(valid) // 2],
        "one bit flipped": bytes(flipped),
        "extended": valid + b"\x00",
        "another model's": foreign,
    }


def test_deserializing_garbage_is_an_error_with_a_message(bench, slaves):
    valid = bench.serialize(bench.get_state())
    ctl = slaves("controller")
    ctl.init()
    foreign = ctl.serialize(ctl.get_state())
    for label, data in garbage_cases(valid, foreign).items():
        mark = bench.mark()
        status, st = bench.deserialize(data)
        assert status == ERROR, f"{label}: {STATUS[status]}"
        assert st.value is None, label
        assert bench.since(mark, ERROR), f"{label}: no log line"
    # zero bytes with a NULL buffer
    status, st = bench.deserialize(b"")
    assert status == ERROR
    # the instance survived all that
    status, st = bench.deserialize(valid)
    assert status == OK and bench.set_state(st) == OK


def test_a_state_of_another_model_is_refused(slaves):
    ctl = slaves("controller")
    ctl.init()
    bench = slaves("bench")
    bench.init()
    st = ctl.get_state()
    mark = bench.mark()
    assert bench.set_state(st) == ERROR
    assert bench.since(mark, ERROR)


@pytest.mark.parametrize("name", ["bench", "servovalve", "actuator"])
def test_two_instances_do_not_disturb_each_other(slaves, fmus, name):
    outputs = fmus[name].names("output")
    d1 = DRIVE[name]

    def d2(t):  # another input history: reversed command or flows, other amplitude
        return {k: (-0.5 * x if k in ("u", "u1", "u2", "Q1", "Q2") else x)
                for k, x in d1(t).items()}

    n = 25
    alone1 = slaves(name)
    alone1.init()
    ref1 = run(alone1, 0.0, n, d1, outputs)
    alone2 = slaves(name)
    alone2.init()
    ref2 = run(alone2, 0.0, n, d2, outputs)
    assert ref1 != ref2

    a, b = slaves(name), slaves(name)
    a.init()
    b.init()
    got1, got2 = [], []
    for k in range(n):
        t = k * H
        got1 += run_one(a, t, d1, outputs)
        got2 += run_one(b, t, d2, outputs)
    assert same(got1, ref1, outputs)
    assert same(got2, ref2, outputs)


def run_one(s, t, drive, outputs):
    assert s.set_reals(drive(t)) == OK
    assert s.step(t, H) == OK
    return [[bits(x) for x in s.get_reals(outputs)]]
