//! The systems of `bench.ssp`: components, wiring and parameter bindings.
//!
//! The parameter bindings are derived, not typed: each component model is given the
//! whole-bench parameter tree of `bench.fmu` (`Params::thesis_bench(mode)`) and every
//! FMU parameter whose value then differs from the component's own default is bound.
//! So the system of components and `bench.fmu` describe the same physics by
//! construction, and a change of the thesis defaults reaches both.
//!
//! Instance names differ from the first segment of every variable name of their FMU
//! (`SV1` holds `sv1.rated_flow`, `Actuator` holds `actuator.dead_volume`): OMSimulator
//! reads a name whose first segment is the instance's own as a path into the instance
//! and strips it, so `actuator.dead_volume` of an instance `actuator` would not be found.

use hbfmu::models::{actuator, controller, manifold, reference, servovalve, HasParams};
use hbfmu::slave::{Model, Value};
use hbmodel::control::trajectory::{THESIS_HIGH, THESIS_LOW, THESIS_MOVE_DURATION};
use hbmodel::manifold::Circuit;
use hbmodel::{Mode, Params};

use super::{Component, Connection, End, System};

/// Mode bound in SystemStructure.ssd; the parameter sets of all three ship beside it.
pub const DEFAULT_MODE: Mode = Mode::ThreeWay;

/// Instance names of the components.
pub const SV1: &str = "SV1";
pub const SV2: &str = "SV2";
pub const MANIFOLD: &str = "Manifold";
pub const ACTUATOR: &str = "Actuator";
pub const CONTROLLER: &str = "Controller";
pub const REFERENCE: &str = "Reference";

/// The closed-loop experiment the package's SSDs run by themselves: the thesis's
/// 7th-order move from -10 mm to +10 mm in 0.2 s, starting at 20 ms (after the
/// initialisation transient), and 80 ms of settling.
pub const MOVE_START: f64 = 0.02;
pub const MOVE_STOP: f64 = MOVE_START + THESIS_MOVE_DURATION + 0.08;

/// Port wiring (ARCHITECTURE.md, port causality): valves take port pressures and give flows;
/// the manifold takes valve flows and chamber pressures and gives port pressures and
/// chamber flows; the actuator takes chamber flows and gives pressures and motion. The
/// same in every mode: the mode only changes what the manifold joins inside (mode 1:
/// SV2 stays connected at null; mode 3: the B ports drain to tank through the reducers).
const WIRES: [(&str, &str, &str, &str); 16] = [
    (SV1, "Q_A", MANIFOLD, "Q_A1"),
    (SV1, "Q_B", MANIFOLD, "Q_B1"),
    (SV2, "Q_A", MANIFOLD, "Q_A2"),
    (SV2, "Q_B", MANIFOLD, "Q_B2"),
    // the valves' flow sensitivities: the manifold's solver closes the stiff loop of
    // each valve orifice with its small port volume implicitly (docs/cosim.md)
    (SV1, "dQ_A_dP_A", MANIFOLD, "dQ_A1_dP_A1"),
    (SV1, "dQ_B_dP_B", MANIFOLD, "dQ_B1_dP_B1"),
    (SV2, "dQ_A_dP_A", MANIFOLD, "dQ_A2_dP_A2"),
    (SV2, "dQ_B_dP_B", MANIFOLD, "dQ_B2_dP_B2"),
    (MANIFOLD, "P_A1", SV1, "P_A"),
    (MANIFOLD, "P_B1", SV1, "P_B"),
    (MANIFOLD, "P_A2", SV2, "P_A"),
    (MANIFOLD, "P_B2", SV2, "P_B"),
    (MANIFOLD, "Q1", ACTUATOR, "Q1"),
    (MANIFOLD, "Q2", ACTUATOR, "Q2"),
    (ACTUATOR, "P1", MANIFOLD, "P1"),
    (ACTUATOR, "P2", MANIFOLD, "P2"),
    // + the chamber port's terms, same name at both ends (bench_system adds them)
];

/// Every parameter of model M whose value under `params` differs from M's default.
fn bindings<M: Model + HasParams>(params: &Params) -> Result<Vec<(String, Value)>, String> {
    let fresh = M::instantiate(None)?;
    let mut bound = M::instantiate(None)?;
    *bound.params_mut() = params.clone();
    Ok(M::variables()
        .into_iter()
        .filter(|v| v.decl.causality == modeldesc::Causality::Parameter)
        .filter_map(|v| {
            let (a, b) = ((v.get)(&fresh), (v.get)(&bound));
            (a != b).then(|| (v.decl.name.clone(), b))
        })
        .collect())
}

fn names<M: Model>(causality: modeldesc::Causality) -> Vec<String> {
    M::variables()
        .into_iter()
        .filter(|v| v.decl.causality == causality)
        .map(|v| v.decl.name)
        .collect()
}

/// An instance `name` of the packaged `fmu` with these bindings.
fn instance<M: Model>(name: &str, fmu: &str, parameters: Vec<(String, Value)>) -> Component {
    use modeldesc::Causality as C;
    Component {
        name: name.into(),
        source: format!("resources/{fmu}.fmu"),
        inputs: names::<M>(C::Input),
        outputs: names::<M>(C::Output),
        parameters,
    }
}

fn component<M: Model + HasParams>(
    name: &str,
    fmu: &str,
    params: &Params,
) -> Result<Component, String> {
    Ok(instance::<M>(name, fmu, bindings::<M>(params)?))
}

/// The parameter trees of the four components for the whole-bench tree `p`.
fn component_params(p: &Params) -> [Params; 4] {
    let mut sv2 = p.clone();
    // SV2 is a servovalve.fmu instance; its `sv1.*` parameters carry SV2's values
    sv2.sv1 = *p.sv2_effective();
    let mut act = p.clone();
    // bench.fmu merges the chamber-side half of each N-V passage into the chamber
    // (Circuit::chamber_volume); the manifold FMU leaves it to the actuator, whose only
    // way to hold it is its dead volume (the sides are equal: one passage geometry)
    let extra = Circuit::from_params(p).chamber_volume;
    act.actuator.dead_volume += 0.5 * (extra[0] + extra[1]);
    [p.clone(), sv2, p.clone(), act]
}

/// Keep on each component the connectors a connection uses. An SSD may expose a subset
/// of an FMU's variables; an engine that sets every declared input each step (fmpy.ssp,
/// from a value it initialises to 0) then leaves the others, such as the valves' supply
/// pressure P_P, at their FMU start values.
fn declare_connected(sys: &mut System) {
    let used = |name: &str, var: &str, start: bool| {
        sys.connections.iter().any(|c| {
            let e = if start { &c.start } else { &c.end };
            e.element.as_deref() == Some(name) && e.connector == var
        })
    };
    let kept: Vec<(Vec<String>, Vec<String>)> = sys
        .components
        .iter()
        .map(|c| {
            let keep = |list: &[String], start| {
                list.iter()
                    .filter(|v| used(&c.name, v, start))
                    .cloned()
                    .collect()
            };
            (keep(&c.inputs, false), keep(&c.outputs, true))
        })
        .collect();
    for (c, (inputs, outputs)) in sys.components.iter_mut().zip(kept) {
        (c.inputs, c.outputs) = (inputs, outputs);
    }
}

fn end(element: &str, connector: &str) -> End {
    End {
        element: Some(element.into()),
        connector: connector.into(),
    }
}

fn wire(a: &str, out: &str, b: &str, inp: &str) -> Connection {
    Connection {
        start: end(a, out),
        end: end(b, inp),
    }
}

/// The bench of `bench.fmu` (thesis parameters, all effects but the payload) in `mode`,
/// as a system of servovalve, manifold and actuator FMUs. Its inputs (SV1.u, SV2.u,
/// Actuator.F_ext) hold their start values (valves at null, no load) unless the master
/// sets them.
pub fn bench_system(mode: Mode) -> Result<System, String> {
    let mut sys = components_of_bench(mode)?;
    declare_connected(&mut sys);
    Ok(sys)
}

/// [`bench_system`] with every connector of its components declared.
fn components_of_bench(mode: Mode) -> Result<System, String> {
    let p = Params::thesis_bench(mode);
    let [sv1p, sv2p, mp, ap] = component_params(&p);
    // The listing is the Gauss-Seidel order. The actuator goes first: its carried model
    // of the passage must start from the manifold's state at t_n; the manifold, last,
    // starts its carried chamber pressures from the actuator's t_n+1, which costs less
    // accuracy than the converse (docs/cosim.md).
    let components = vec![
        component::<actuator::ActuatorFmu>(ACTUATOR, "actuator", &ap)?,
        component::<servovalve::ServovalveFmu>(SV1, "servovalve", &sv1p)?,
        component::<servovalve::ServovalveFmu>(SV2, "servovalve", &sv2p)?,
        component::<manifold::ManifoldFmu>(MANIFOLD, "manifold", &mp)?,
    ];
    let mut connections: Vec<Connection> =
        WIRES.iter().map(|(a, b, c, d)| wire(a, b, c, d)).collect();
    // the chamber port (docs/cosim.md): each side carries the other's element over a
    // step, the manifold the chamber (displaced flow, volume, bulk modulus), the actuator
    // the passage and the node behind it (driving pressure, inertance, volume, feed)
    let chamber_port = actuator::CHAMBER_OUTPUTS
        .iter()
        .map(|v| (ACTUATOR, v.0, MANIFOLD))
        .chain(
            actuator::PASSAGE_INPUTS
                .iter()
                .map(|v| (MANIFOLD, v.0, ACTUATOR)),
        );
    connections.extend(chamber_port.map(|(a, name, b)| wire(a, name, b, name)));
    Ok(System {
        name: "HydroBench".into(),
        inputs: vec![],
        outputs: vec![],
        components,
        connections,
    })
}

/// Variant SSDs of the closed loop, one per mode (SSP 1.0 section 3: further SSD files
/// at the package root are variants; a tool without variant support reads
/// SystemStructure.ssd alone). Mode 1 drives the actuator with SV1 alone and leaves SV2
/// at null (the controller's u2 is not connected); modes 2 and 3 drive both valves.
pub const CLOSED_LOOP_SSD: &str = "ClosedLoop.ssd";
pub const CLOSED_LOOP_MODE1_SSD: &str = "ClosedLoopMode1.ssd";
pub const CLOSED_LOOP_MODE2_SSD: &str = "ClosedLoopMode2.ssd";

/// The variant SSD holding the closed loop in `mode`.
pub fn closed_loop_ssd(mode: Mode) -> &'static str {
    match mode {
        Mode::FourWaySingle => CLOSED_LOOP_MODE1_SSD,
        Mode::FourWayParallel => CLOSED_LOOP_MODE2_SSD,
        Mode::ThreeWay => CLOSED_LOOP_SSD,
    }
}

/// The reference.fmu bindings of the package's experiment: one move of the thesis cycle
/// starting at MOVE_START (the return, a half period later, lies beyond MOVE_STOP).
pub fn move_reference() -> Vec<(String, Value)> {
    [
        ("move.from", THESIS_LOW),
        ("move.to", THESIS_HIGH),
        ("move.start", MOVE_START),
        ("move.duration", THESIS_MOVE_DURATION),
    ]
    .iter()
    .map(|(n, x)| (n.to_string(), Value::Real(*x)))
    .collect()
}

/// The system of [`bench_system`] closed by a `controller.fmu` instance fed by a
/// `reference.fmu` instance: the whole experiment (the move of [`move_reference`]) runs
/// from the SSD alone, with no input from outside. The controller reads the actuator's
/// y, P1, P2 (the plant's own values: the components have no acquisition delay) and the
/// reference with its derivatives, and drives the valves. It samples at its own 1 ms
/// period whatever the engine's step (`self_sampled`). Its built-in law is the thesis's
/// proportional one (Kp = 1169 V/m).
pub fn closed_loop_system(mode: Mode) -> Result<System, String> {
    let mut sys = components_of_bench(mode)?;
    sys.name = format!("HydroBenchClosedLoopMode{}", mode.number());
    let controller = instance::<controller::ControllerFmu>(
        CONTROLLER,
        "controller",
        vec![
            ("self_sampled".into(), Value::Boolean(true)),
            ("reference_derivatives".into(), Value::Boolean(true)),
        ],
    );
    let reference = instance::<reference::ReferenceFmu>(REFERENCE, "reference", move_reference());
    // the piston starts where the move does
    for c in sys.components.iter_mut().filter(|c| c.name == ACTUATOR) {
        c.parameters.retain(|(n, _)| n != "y0");
        c.parameters.push(("y0".into(), Value::Real(THESIS_LOW)));
    }
    // the reference first: its outputs at t_n are the controller's sample at t_n
    sys.components.insert(0, reference);
    sys.components.push(controller);
    let mut wires = vec![
        (ACTUATOR, "y", CONTROLLER, "y"),
        (ACTUATOR, "P1", CONTROLLER, "P1"),
        (ACTUATOR, "P2", CONTROLLER, "P2"),
        (CONTROLLER, "u1", SV1, "u"),
    ];
    if mode != Mode::FourWaySingle {
        wires.push((CONTROLLER, "u2", SV2, "u"));
    }
    for signal in ["y_ref", "dy_ref", "d2y_ref", "d3y_ref", "P_ref"] {
        wires.push((REFERENCE, signal, CONTROLLER, signal));
    }
    sys.connections
        .extend(wires.iter().map(|(a, b, c, d)| wire(a, b, c, d)));
    declare_connected(&mut sys);
    Ok(sys)
}

#[cfg(test)]
mod tests {
    use super::super::read::parse_ssd;
    use super::super::write::to_ssd;
    use super::*;

    #[test]
    fn ssd_round_trips_and_binds_what_the_bench_changes() {
        for mode in [Mode::FourWaySingle, Mode::FourWayParallel, Mode::ThreeWay] {
            let sys = bench_system(mode).unwrap();
            let back = parse_ssd(&to_ssd(&sys, 0.35)).unwrap();
            assert_eq!(back, sys, "{mode:?}");
            let m = sys.component(MANIFOLD).unwrap();
            let bound =
                |c: &Component, n: &str| c.parameters.iter().find(|(k, _)| k == n).map(|(_, v)| *v);
            // mode 3 is the manifold's default: bound only when it differs
            let want = (mode != Mode::ThreeWay).then_some(Value::Integer(mode.number() as i32));
            assert_eq!(bound(m, "mode"), want);
            assert_eq!(bound(m, "effect.entrained_air"), Some(Value::Boolean(true)));
            let a = sys.component(ACTUATOR).unwrap();
            let Some(Value::Real(v)) = bound(a, "actuator.dead_volume") else {
                panic!("dead volume not bound")
            };
            assert!(v > hbmodel::params::ActuatorParams::default().dead_volume);
            // both ends of every chamber-port term are wired, by the same name
            let wired = |from: &str, name: &str, to: &str| {
                sys.connections.iter().any(|c| {
                    c.start.element.as_deref() == Some(from)
                        && c.end.element.as_deref() == Some(to)
                        && c.start.connector == name
                        && c.end.connector == name
                })
            };
            for (name, _, _) in actuator::CHAMBER_OUTPUTS {
                assert!(wired(ACTUATOR, name, MANIFOLD), "{name}");
            }
            for (name, _, _) in actuator::PASSAGE_INPUTS {
                assert!(wired(MANIFOLD, name, ACTUATOR), "{name}");
            }
            // the closed loop: the controller drives SV2 except in mode 1
            let cl = closed_loop_system(mode).unwrap();
            assert_eq!(parse_ssd(&to_ssd(&cl, 0.35)).unwrap(), cl);
            let drives = |valve: &str| {
                cl.connections.iter().any(|c| {
                    c.start.element.as_deref() == Some(CONTROLLER)
                        && c.end.element.as_deref() == Some(valve)
                })
            };
            assert!(drives(SV1));
            assert_eq!(drives(SV2), mode != Mode::FourWaySingle);
            for s in [&sys, &cl] {
                // libcosim resolves component-to-component connections only
                assert!(s
                    .connections
                    .iter()
                    .all(|c| c.start.element.is_some() && c.end.element.is_some()));
                // OMSimulator strips a first name segment equal to the instance's name
                for c in &s.components {
                    for (n, _) in &c.parameters {
                        assert_ne!(n.split('.').next(), Some(c.name.as_str()), "{n}");
                    }
                }
            }
            // every controller input is driven: nothing is left open
            let fed: Vec<&str> = cl
                .connections
                .iter()
                .filter(|c| c.end.element.as_deref() == Some(CONTROLLER))
                .map(|c| c.end.connector.as_str())
                .collect();
            for input in &cl.component(CONTROLLER).unwrap().inputs {
                assert!(fed.contains(&input.as_str()), "{input}");
            }
        }
    }
}
