//! Every packaged HydroBench FMU, loaded and co-simulated through the `fmi` crate
//! (jondo2010/rust-fmi): an FMI 2.0 importer we did not write.
//!
//! The FMUs come from `HB_FMU_DIR` (relative paths from the workspace root) or, by
//! default, `<workspace>/target/fmu`; `bash tools/test.sh` builds and packages them
//! before `cargo test`. For each FMU the test checks the model description the importer
//! parsed (identifier, capabilities, every variable, the named inputs and outputs,
//! ModelStructure/Outputs), runs the Co-Simulation life cycle
//! (instantiate, setup, enter/exit initialization, set inputs, step, read outputs,
//! terminate), asserts the physics of the result, and rolls the FMU back through
//! get/set and serialize/deserialize of its state, which must replay bit for bit.

mod harness;

use std::rc::Rc;

use fmi::fmi2::instance::{CoSimulation as _, Common};
use fmi::fmi2::Fmi2Error;

use harness::*;
// ---------------------------------------------------------------------------------------
// The five FMUs

#[test]
fn servovalve_opens_p_to_a_and_b_to_t() {
    let inputs = ["u", "P_P", "P_T", "P_A", "P_B"];
    let out = ["Q_A", "Q_B", "x_s"];
    let mut sim = Sim::new("servovalve", import("servovalve", &inputs, &out), "sv-step");
    sim.initialize(&[], &[]);
    let (p_p, p_t) = pair(sim.get(&["P_P", "P_T"]));
    assert!(p_p > p_t, "supply {p_p} Pa not above tank {p_t} Pa");
    let mid = 0.5 * (p_p + p_t);
    sim.set(&[("P_A", mid), ("P_B", mid)]);
    let rest = sim.get(&out);

    // a 5 V step at t = 0; 40 steps of 0.1 ms
    sim.set(&[("u", 5.0)]);
    let traj = sim.run(40, 1e-4, &out);
    let (q_a, q_b, x_s) = (traj[39][0], traj[39][1], traj[39][2]);

    // reference: a valve initialized at 5 V starts with its spool at rest there
    let mut held = Sim::new("servovalve", import("servovalve", &inputs, &out), "sv-held");
    held.initialize(&[("u", 5.0), ("P_A", mid), ("P_B", mid)], &[]);
    let steady = held.get(&out);
    let peak = column(&traj, 2).into_iter().fold(0.0, f64::max);
    eprintln!(
        "servovalve: at rest {rest:?}; at {} s after a 5 V step Q_A = {q_a:e}, Q_B = {q_b:e}, \
         x_s = {x_s:e} (peak {peak:e}); held at 5 V: {steady:?}",
        sim.t
    );
    assert!(q_a > 0.0, "Q_A = {q_a:e} m3/s: P->A should open");
    assert!(q_b < 0.0, "Q_B = {q_b:e} m3/s: B->T should open");
    assert!(x_s > 0.0, "x_s = {x_s:e} m");
    // equal port pressures, symmetric lands: as much comes back through B as leaves A
    assert!(rel_close(-q_b, q_a, 0.02), "Q_A = {q_a:e}, Q_B = {q_b:e}");
    // closed at 0 V (null leakage cancels at equal port pressures), open at 5 V
    assert!(rest[0].abs() < 1e-3 * q_a, "Q_A at 0 V: {:e}", rest[0]);
    // the second-order spool settles on the held valve's opening, overshooting a little
    assert!(
        rel_close(x_s, steady[2], 0.01),
        "x_s = {x_s:e}, held {:e}",
        steady[2]
    );
    assert!(
        rel_close(q_a, steady[0], 0.01),
        "Q_A = {q_a:e}, held {:e}",
        steady[0]
    );
    assert!(
        peak < 1.3 * steady[2],
        "overshoot: peak {peak:e}, held {:e}",
        steady[2]
    );
    held.terminate();

    sim.check_rollback(20, 1e-4, &out);
    sim.terminate();
}

#[test]
fn manifold_delivers_port_flows_to_the_chambers() {
    let inputs = ["Q_A1", "Q_B1", "Q_A2", "Q_B2", "P1", "P2"];
    let outputs = ["P_A1", "P_B1", "P_A2", "P_B2", "Q1", "Q2"];
    let q = 1e-4;
    // mode 3: SV1's port A feeds chamber 1, SV2's port A drains chamber 2;
    // mode 1: SV1 alone, its A to chamber 1 and B to chamber 2
    for (mode, flows, [feed, drain]) in [
        (3, [("Q_A1", q), ("Q_A2", -q)], [0, 2]),
        (1, [("Q_A1", q), ("Q_B1", -q)], [0, 1]),
    ] {
        let imp = import("manifold", &inputs, &outputs);
        let mut sim = Sim::new("manifold", imp, &format!("manifold-mode{mode}"));
        sim.initialize(&[], &[("mode", mode)]);
        let mut k = [0];
        let r = sim.inst.get_integer(&[sim.vr("mode")], &mut k);
        sim.check("fmi2GetInteger(mode)", r);
        assert_eq!(k[0], mode, "mode read back");
        let (p1, p2) = pair(sim.get(&["P1", "P2"]));
        sim.set(&flows);
        // the passages' inertance rings against the port volumes (about 1 kHz, barely
        // damped with the chamber pressures held): 50 steps of 20 ms to steady state
        let traj = sim.run(50, 0.02, &outputs);
        let o = &traj[49];
        eprintln!(
            "manifold mode {mode} at {} s: {:?}",
            sim.t,
            outputs.iter().zip(o).collect::<Vec<_>>()
        );
        let (q1, q2) = (o[4], o[5]);
        assert!(
            rel_close(q1, q, 0.01),
            "mode {mode}: Q1 = {q1:e}, fed {q:e}"
        );
        assert!(
            rel_close(q2, -q, 0.01),
            "mode {mode}: Q2 = {q2:e}, fed {:e}",
            -q
        );
        // pressure drops along the passages: the feeding port above chamber 1, the
        // draining port below chamber 2
        assert!(
            o[feed] > p1,
            "mode {mode}: feeding port at {} Pa, P1 = {p1} Pa",
            o[feed]
        );
        assert!(
            o[drain] < p2,
            "mode {mode}: draining port at {} Pa, P2 = {p2} Pa",
            o[drain]
        );
        sim.check_rollback(20, 1e-4, &outputs);
        sim.terminate();
    }
}

#[test]
fn actuator_moves_at_flow_over_area() {
    let out = ["P1", "P2", "y", "v", "a"];
    let imp = import("actuator", &["Q1", "Q2", "F_ext"], &out);
    let mut sim = Sim::new("actuator", imp, "actuator-import");
    sim.initialize(&[], &[]);
    let area = sim.get1("actuator.area");
    let y0 = sim.get1("y");
    let q = 1e-4;
    let v_ideal = q / area;
    assert!(rel_close(v_ideal, 0.106, 0.01), "Q/A = {v_ideal} m/s");
    sim.set(&[("Q1", q), ("Q2", -q)]);
    // 50 steps of 2 ms
    let traj = sim.run(50, 2e-3, &out);
    let (y, v) = (column(&traj, 2), column(&traj, 3));
    let dp: Vec<f64> = traj.iter().map(|r| r[0] - r[1]).collect();
    // the oil column rings (about 300 Hz) around the mean motion: judge the mean velocity
    // over the last 40 ms by the travel, and the ringing by its decay
    let v_mean = (y[49] - y[29]) / (20.0 * 2e-3);
    let ring = |vs: &[f64]| vs.iter().map(|x| (x - v_ideal).abs()).fold(0.0, f64::max);
    let (ring_start, ring_end) = (ring(&v[..10]), ring(&v[40..]));
    eprintln!(
        "actuator: Q/A = {v_ideal} m/s; mean v over the last 40 ms {v_mean} m/s; v at {} s \
         {}; ringing {ring_start} -> {ring_end} m/s; mean P1 - P2 {} Pa",
        sim.t,
        v[49],
        mean(&dp[30..])
    );
    // internal leakage lets a little flow by the piston: the mean just under Q/A
    assert!(
        v_mean > 0.97 * v_ideal && v_mean < 1.005 * v_ideal,
        "mean v = {v_mean} m/s, Q/A = {v_ideal} m/s"
    );
    assert!(
        rel_close(v[49], v_ideal, 0.1),
        "v = {} m/s at the end",
        v[49]
    );
    assert!(
        ring_end < 0.5 * ring_start,
        "ringing does not decay: {ring_start} -> {ring_end}"
    );
    assert!(
        y[49] - y0 > 0.9 * v_ideal * sim.t,
        "travel {} m",
        y[49] - y0
    );
    // chamber 1 lifts the rod's weight and overcomes friction
    assert!(
        mean(&dp[30..]) > 0.0,
        "mean P1 - P2 = {} Pa",
        mean(&dp[30..])
    );
    sim.check_rollback(20, 1e-3, &out);
    sim.terminate();
}

#[test]
fn bench_piston_moves_up_on_positive_commands() {
    let outputs = [
        "y", "v", "a", "P1", "P2", "P_A1", "P_B1", "P_A2", "P_B2", "Q1", "Q2",
    ];
    let bench = |name| {
        let mut sim = Sim::new(
            "bench",
            import("bench", &["u1", "u2", "F_ext"], &outputs),
            name,
        );
        sim.initialize(&[], &[]);
        sim
    };
    let mut sim = bench("bench-fine");
    let mut mode = [0];
    let r = sim.inst.get_integer(&[sim.vr("mode")], &mut mode);
    sim.check("fmi2GetInteger(mode)", r);
    assert_eq!(mode[0], 3, "bench.fmu's default mode");
    // the thesis bench: every effect on but the payload
    let switches = [
        "effect.payload",
        "effect.valve_dynamics",
        "effect.dry_friction",
    ];
    let vrs: Vec<u32> = switches.iter().map(|n| sim.vr(n)).collect();
    let mut on = [-1; 3];
    let r = sim.inst.get_boolean(&vrs, &mut on);
    sim.check(&format!("fmi2GetBoolean({switches:?})"), r);
    assert_eq!(on, [0, 1, 1], "{switches:?}");
    let y0 = sim.get1("y");

    // u1 = 2 V opens SV1 P->A into chamber 1, u2 = -2 V opens SV2 A->T out of chamber 2:
    // 40 steps of 0.5 ms
    sim.set(&[("u1", 2.0), ("u2", -2.0)]);
    let traj = sim.run(40, 5e-4, &outputs);
    let y = column(&traj, 0);
    let dp: Vec<f64> = traj.iter().map(|r| r[3] - r[4]).collect();
    let o = &traj[39];
    eprintln!(
        "bench at {} s: {:?}; mean P1 - P2 over the last 10 ms {} Pa",
        sim.t,
        outputs.iter().zip(o).collect::<Vec<_>>(),
        mean(&dp[20..])
    );
    assert!(
        y[39] > y0,
        "y = {} m from y0 = {y0} m: the piston should move up",
        y[39]
    );
    for (k, w) in y.windows(2).enumerate() {
        assert!(
            w[1] > w[0],
            "y fell between steps {} and {}: {w:?}",
            k + 1,
            k + 2
        );
    }
    for r in &traj {
        assert!(
            r[9] > 0.0 && r[10] < 0.0,
            "Q1 = {:e}, Q2 = {:e}",
            r[9],
            r[10]
        );
    }
    // The oil column rings at the bench's hydraulic mode (about 230 Hz) with little
    // damping, so P1 - P2 swings through zero each period; on average over the last
    // 10 ms (two periods) chamber 1 carries the rod's weight and friction.
    assert!(
        mean(&dp[20..]) > 0.0,
        "mean P1 - P2 = {} Pa",
        mean(&dp[20..])
    );

    // the communication step does not change the physics: 10 steps of 2 ms land on the
    // same state as 40 of 0.5 ms
    let mut coarse = bench("bench-coarse");
    coarse.set(&[("u1", 2.0), ("u2", -2.0)]);
    let c = coarse.run(10, 2e-3, &outputs);
    let (yc, vc) = (c[9][0], c[9][1]);
    assert!(
        (yc - y[39]).abs() < 1e-3 * (y[39] - y0).abs(),
        "y at 20 ms: {} with 0.5 ms steps, {yc} with 2 ms steps",
        y[39]
    );
    assert!(
        (vc - o[1]).abs() < 1e-3 * o[1].abs(),
        "v at 20 ms: {} and {vc}",
        o[1]
    );
    coarse.terminate();

    sim.check_rollback(10, 1e-3, &outputs);
    sim.terminate();
}

#[test]
fn controller_is_proportional_and_instances_are_independent() {
    let inputs = ["y_ref", "y", "P1", "P2", "P_ref"];
    // two instances of one FMU in one process (one loaded library), different gains
    let imp = Rc::new(import("controller", &inputs, &["u1", "u2"]));
    let mut thesis = Sim::new("controller", imp.clone(), "ctrl-thesis");
    let mut soft = Sim::new("controller", imp, "ctrl-soft");
    thesis.initialize(&[], &[]);
    soft.initialize(&[("Kp", 500.0)], &[]);
    let mut law = [0];
    let r = thesis.inst.get_integer(&[thesis.vr("law")], &mut law);
    thesis.check("fmi2GetInteger(law)", r);
    assert_eq!(law[0], 1, "law: proportional");
    let kp = thesis.get1("Kp");
    assert_eq!(kp, 1169.0, "the thesis gain by default");
    assert_eq!(soft.get1("Kp"), 500.0, "the gain set before initialization");

    let y_ref = 0.004;
    thesis.set(&[("y_ref", y_ref)]);
    soft.set(&[("y_ref", y_ref)]);
    // 30 steps of 1 ms; the piston creeps towards, then past, the reference
    for k in 0..30 {
        let y = 3e-4 * k as f64;
        for (sim, kp) in [(&mut thesis, kp), (&mut soft, 500.0)] {
            sim.set(&[("y", y)]);
            let (u1, u2) = pair(sim.get(&["u1", "u2"]));
            let want = kp * (y_ref - y);
            assert!(
                (u1 - want).abs() <= 1e-12 * want.abs().max(1.0),
                "{}: u1 = {u1} V at y = {y} m, Kp (y_ref - y) = {want} V",
                sim.name
            );
            assert_eq!(u2, -u1, "{}: u2 = -u1", sim.name);
            sim.step(1e-3);
        }
    }
    // saturation at +-10 V
    thesis.set(&[("y", -0.1)]);
    assert_eq!(
        thesis.get(&["u1", "u2"]),
        vec![10.0, -10.0],
        "saturated at +10 V"
    );
    thesis.set(&[("y", 0.1)]);
    assert_eq!(
        thesis.get(&["u1", "u2"]),
        vec![-10.0, 10.0],
        "saturated at -10 V"
    );
    thesis.set(&[("y", 0.0)]);
    thesis.check_rollback(20, 1e-3, &["u1", "u2"]);
    thesis.terminate();
    soft.terminate();
}

/// An FMU's error status and its logged message both reach the host through the
/// importer: a step from the wrong time is refused with fmi2Error and a log line under
/// the instance's name.
#[test]
fn errors_come_back_as_status_and_log_message() {
    let imp = import("controller", &["y"], &["u1"]);
    let mut sim = Sim::new("controller", imp, "ctrl-misuse");
    sim.initialize(&[], &[]);
    let r = sim.inst.do_step(0.5, 1e-3, true);
    assert!(
        matches!(r, Err(Fmi2Error::Error)),
        "fmi2DoStep at the wrong time returned {r:?}"
    );
    let msgs = messages_of("ctrl-misuse");
    assert!(
        msgs.iter()
            .any(|(l, m)| *l == log::Level::Error && m.contains("fmi2DoStep")),
        "no error message about fmi2DoStep reached the host: {msgs:?}"
    );
}
