"""Model descriptions: fmpy's validation, the official FMI 2.0 schema, ModelStructure, and the
variables, types and units issue 4 fixes for each FMU."""
from __future__ import annotations

import os
import re

import fmpy
import pytest
from fmpy.validation import validate_fmu
from lxml import etree

from conftest import NAMES

EFFECTS = [
    "manifold_volume", "manifold_inertia", "manifold_losses", "entrained_air",
    "internal_leakage", "dry_friction", "viscous_friction", "valve_dynamics",
    "valve_asymmetry", "sensor_delay", "payload", "temperature",
]

# the chamber port's coupling terms (docs/cosim.md): the actuator's chamber terms feed
# the manifold, the manifold's passage terms feed the actuator
CHAMBER_TERMS = {f"{n}{k}{s}": u for k in "12"
                 for n, s, u in (("Q", "_displaced", "m3/s"), ("V", "", "m3"), ("beta", "", "Pa"))}
PASSAGE_TERMS = {f"{n}{k}{s}": u for k in "12"
                 for n, s, u in (("P", "_drive", "Pa"), ("L", "", "kg/m4"), ("V", "_drive", "m3"),
                                 ("beta", "_drive", "Pa"), ("Q", "_feed", "m3/s"))}

# name -> unit (None: no unit) per FMU, as issue 4 names them
REQUIRED = {
    "servovalve": {
        "input": {"u": "V", "P_P": "Pa", "P_T": "Pa", "P_A": "Pa", "P_B": "Pa"},
        "output": {"Q_A": "m3/s", "Q_B": "m3/s", "x_s": "m"},
        "parameter": {},
    },
    "manifold": {
        "input": {"Q_A1": "m3/s", "Q_B1": "m3/s", "Q_A2": "m3/s", "Q_B2": "m3/s",
                  "P1": "Pa", "P2": "Pa",
                  # the valves' flow sensitivities, for stable co-simulation (docs/cosim.md)
                  **{f"dQ_{p}{k}_dP_{p}{k}": "m3/(s.Pa)" for p in "AB" for k in "12"},
                  # the actuator's chamber terms, for the chamber port (docs/cosim.md)
                  **CHAMBER_TERMS},
        "output": {"P_A1": "Pa", "P_B1": "Pa", "P_A2": "Pa", "P_B2": "Pa",
                   "Q1": "m3/s", "Q2": "m3/s",
                   # the passages at the chambers and the nodes behind them (docs/cosim.md)
                   **PASSAGE_TERMS},
        "parameter": {"mode": None},
    },
    "actuator": {
        "input": {"Q1": "m3/s", "Q2": "m3/s", "F_ext": "N",
                  # the manifold's passage terms, for the chamber port (docs/cosim.md)
                  **PASSAGE_TERMS},
        "output": {"P1": "Pa", "P2": "Pa", "y": "m", "v": "m/s", "a": "m/s2",
                   **CHAMBER_TERMS},
        "parameter": {},
    },
    "bench": {
        "input": {"u1": "V", "u2": "V", "F_ext": "N"},
        "output": {"y": "m", "v": "m/s", "a": "m/s2", "P1": "Pa", "P2": "Pa",
                   "P_A1": "Pa", "P_B1": "Pa", "P_A2": "Pa", "P_B2": "Pa",
                   "Q1": "m3/s", "Q2": "m3/s"},
        "parameter": {"mode": None, "P_supply": "Pa", "P_tank": "Pa", "y0": "m",
                      "payload_mass": "kg", **{f"effect.{e}": None for e in EFFECTS}},
    },
    "controller": {
        "input": {"y_ref": "m", "y": "m", "P1": "Pa", "P2": "Pa", "P_ref": "Pa",
                  # the reference's derivatives, used when reference_derivatives is true
                  "dy_ref": "m/s", "d2y_ref": "m/s2", "d3y_ref": "m/s3"},
        "output": {"u1": "V", "u2": "V"},
        "parameter": {"law": None, "Kp": "V/m"},
    },
}

# SI unit -> (base-unit exponents, display unit, factor) the project promises
DISPLAY = {
    "Pa": ({"kg": 1, "m": -1, "s": -2}, "bar", 1e-5),
    "m3/s": ({"m": 3, "s": -1}, "L/min", 60000.0),
    "m": ({"m": 1}, "mm", 1000.0),
}

XSD = os.path.join(os.path.dirname(fmpy.__file__), "schema", "fmi2", "fmi2ModelDescription.xsd")


@pytest.fixture(scope="module")
def schema():
    return etree.XMLSchema(etree.parse(XSD))


def xml_of(fmus, name):
    return etree.parse(str(fmus[name].dir / "modelDescription.xml"))


@pytest.mark.parametrize("name", NAMES)
def test_fmpy_validate_fmu_reports_no_problem(fmu_paths, name):
    assert validate_fmu(str(fmu_paths[name])) == []


@pytest.mark.parametrize("name", NAMES)
def test_model_description_validates_against_the_fmi2_xsd(fmus, schema, name):
    doc = xml_of(fmus, name)
    ok = schema.validate(doc)
    assert ok, "\n".join(str(e) for e in schema.error_log)


@pytest.mark.parametrize("name", NAMES)
def test_model_structure_lists_exactly_the_outputs_and_initial_unknowns(fmus, name):
    root = xml_of(fmus, name).getroot()
    svs = root.find("ModelVariables").findall("ScalarVariable")
    causality = [sv.get("causality", "local") for sv in svs]
    initial = [sv.get("initial") for sv in svs]
    ms = root.find("ModelStructure")

    def indices(section):
        el = ms.find(section)
        return [] if el is None else [int(u.get("index")) for u in el.findall("Unknown")]

    outputs = indices("Outputs")
    derivatives = indices("Derivatives")
    initial_unknowns = indices("InitialUnknowns")
    all_outputs = [i + 1 for i, c in enumerate(causality) if c == "output"]
    assert all_outputs, "an FMU without outputs"
    # FMI 2.0 section 3.3.1: Outputs are all variables with causality output, in index order
    assert outputs == all_outputs
    # InitialUnknowns: outputs with initial approx/calculated, calculated parameters, and
    # states/derivatives with initial approx/calculated, ordered by index
    expected = sorted(
        {i for i in all_outputs if initial[i - 1] in ("approx", "calculated")}
        | {i + 1 for i, c in enumerate(causality) if c == "calculatedParameter"}
        | {i for i in derivatives if initial[i - 1] in ("approx", "calculated")}
    )
    assert initial_unknowns == expected
    # dependencies, when declared, name knowns: inputs (or, for initial unknowns,
    # parameters with initial exact); never outputs
    for section in ("Outputs", "InitialUnknowns"):
        el = ms.find(section)
        for u in el.findall("Unknown"):
            deps = u.get("dependencies")
            if deps:
                for d in map(int, deps.split()):
                    assert causality[d - 1] in ("input", "parameter", "independent") or \
                        d in derivatives, f"{section} {u.get('index')} depends on {d}"


@pytest.mark.parametrize("name", NAMES)
def test_variables_named_as_the_issue_requires(fmus, name):
    u = fmus[name]
    var = u.var
    for causality, required in REQUIRED[name].items():
        declared = u.names(causality)
        missing = sorted(set(required) - set(declared))
        assert not missing, f"{name}: {causality}s {missing} missing (declared {declared})"
        for n, unit in required.items():
            v = var[n]
            assert v.unit == unit or (unit is None and v.unit in (None, "")), \
                f"{name}.{n}: unit {v.unit!r}, expected {unit!r}"
            if causality in ("input", "output"):
                assert v.type == "Real" and v.variability == "continuous", (n, v.type)
            else:
                assert v.variability in ("fixed", "tunable"), (n, v.variability)
    # inputs are the wiring contract: exactly those of the issue
    assert sorted(u.names("input")) == sorted(REQUIRED[name]["input"])


def test_bench_has_one_boolean_switch_per_registry_effect(fmus):
    var = fmus["bench"].var
    switches = sorted(n for n in var if n.startswith("effect."))
    assert switches == sorted(f"effect.{e}" for e in EFFECTS)
    for n in switches:
        assert var[n].type == "Boolean" and var[n].causality == "parameter"
    # README: Params::thesis_bench turns all effects on but the payload
    assert var["effect.payload"].start in ("false", False)
    assert all(var[f"effect.{e}"].start in ("true", True) for e in EFFECTS if e != "payload")
    mode = var["mode"]
    assert mode.type in ("Integer", "Enumeration")
    assert (int(mode.min), int(mode.max)) == (1, 3)
    assert var["P_supply"].causality == var["P_tank"].causality == "parameter"
    assert float(var["P_tank"].start) < float(var["P_supply"].start)


def test_manifold_mode_parameter(fmus):
    mode = fmus["manifold"].var["mode"]
    assert mode.causality == "parameter" and mode.type in ("Integer", "Enumeration")
    assert (int(mode.min), int(mode.max)) == (1, 3)


def test_controller_law_is_an_integer_option_with_proportional(fmus):
    """Selectable options are Integer parameters (libcosim ignores FMI Enumerations) whose
    values are listed in the description as "k = name (meaning)"."""
    law = fmus["controller"].var["law"]
    assert law.type == "Integer" and law.causality == "parameter"
    items = dict((name, int(k)) for k, name in re.findall(r"(?:: |; )(\d+) = (\w+) \(", law.description))
    assert "proportional" in items
    assert sorted(items.values()) == list(range(int(law.min), int(law.max) + 1))
    assert int(law.start) == items["proportional"]
    assert not fmus["controller"].md.typeDefinitions
    kp = fmus["controller"].var["Kp"]
    assert kp.type == "Real" and float(kp.start) > 0


@pytest.mark.parametrize("name", NAMES)
def test_units_are_si_with_the_project_display_units(fmus, name):
    root = xml_of(fmus, name).getroot()
    units = {}
    for unit in root.find("UnitDefinitions").findall("Unit"):
        base = unit.find("BaseUnit")
        exps = {k: int(v) for k, v in (base.attrib.items() if base is not None else [])
                if k not in ("factor", "offset")}
        displays = {d.get("name"): float(d.get("factor", "1")) for d in unit.findall("DisplayUnit")}
        units[unit.get("name")] = (exps, displays)
    used = set()
    for sv in root.find("ModelVariables").findall("ScalarVariable"):
        real = sv.find("Real")
        if real is None or real.get("unit") is None:
            continue
        unit = real.get("unit")
        used.add(unit)
        assert unit in units, f"{sv.get('name')}: unit {unit} not in UnitDefinitions"
        if unit in DISPLAY:
            shown = real.get("displayUnit")
            assert shown == DISPLAY[unit][1], \
                f"{name}.{sv.get('name')}: displayUnit {shown!r} for {unit}"
    for unit in used & set(DISPLAY):
        exps, display, factor = DISPLAY[unit]
        assert units[unit][0] == exps, f"{unit}: base unit {units[unit][0]}"
        assert units[unit][1].get(display) == pytest.approx(factor, rel=1e-12), units[unit][1]


def test_guids_differ_between_fmus(fmus):
    guids = [fmus[n].md.guid for n in NAMES]
    assert len(set(guids)) == len(NAMES)
    for n in NAMES:
        assert fmus[n].md.coSimulation.modelIdentifier == n
        cs = fmus[n].md.coSimulation
        assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
        assert cs.canHandleVariableCommunicationStepSize
