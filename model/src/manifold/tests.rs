//! The network against the thesis's tables (3.2)-(3.4) and the mode-3 topology.

use super::lumped::{path_to_chamber, reference_network};
use super::*;
use crate::params::LPM;

const RHO: f64 = 862.0;

#[test]
fn added_volumes_reproduce_table_3_3() {
    for (mode, v) in [
        (Mode::FourWaySingle, 1.0041e-4),
        (Mode::FourWayParallel, 1.0041e-4),
        (Mode::ThreeWay, 7.9754e-5),
    ] {
        for got in added_volume(mode) {
            assert!((got / v - 1.0).abs() < 1e-3, "{mode:?}: {got} vs {v}");
        }
    }
}

#[test]
fn equivalent_masses_reproduce_table_3_4() {
    for (mode, m) in [
        (Mode::FourWaySingle, 4.70),
        (Mode::FourWayParallel, 2.80),
        (Mode::ThreeWay, 3.42),
    ] {
        let got = equivalent_mass(mode, RHO, crate::params::ActuatorParams::default().area);
        assert!((got / m - 1.0).abs() < 5e-3, "{mode:?}: {got} vs {m}");
    }
}

#[test]
fn passage_c1_n2_losses_follow_table_3_2() {
    let net = Circuit::network(
        Mode::FourWaySingle,
        &ManifoldConfig {
            volume: true,
            inertia: true,
            losses: true,
            volume_scale: 1.0,
            inertia_scale: 1.0,
            loss_scale: 1.0,
            density: RHO,
            viscosity: RHO * 46e-6, // VG 46 at 40 degC
            piston_area: crate::params::ActuatorParams::default().area,
        },
    );
    let cn = net
        .passages
        .iter()
        .find(|p| p.kind == PassageKind::CN)
        .unwrap();
    for (q_lpm, dp_bar) in [(10.0, 0.05281), (20.0, 0.18360), (30.0, 0.39237)] {
        let got = cn.pressure_drop(q_lpm * LPM) / BAR;
        assert!(
            (got / dp_bar - 1.0).abs() < 0.03,
            "{q_lpm} L/min: {got} bar vs {dp_bar}"
        );
        let back = cn.pressure_drop(-q_lpm * LPM) / BAR;
        assert!((back + got).abs() < 1e-12, "losses oppose the flow");
    }
}

#[test]
fn mode_3_drains_b_ports_through_reducers_and_keeps_dead_legs() {
    let c = reference_network(Mode::ThreeWay, RHO);
    assert_eq!(c.reducers.len(), 2);
    assert!(c.nodes.iter().any(|n| n.name == "D1") && c.nodes.iter().any(|n| n.name == "D2"));
    for v in 0..2 {
        let b = c.valve_ports[v][1];
        assert!(path_to_chamber(&c, b, 0).is_none() && path_to_chamber(&c, b, 1).is_none());
    }
    let c = reference_network(Mode::FourWaySingle, RHO);
    assert!(c.reducers.is_empty());
    assert!(
        path_to_chamber(&c, c.valve_ports[0][1], 1).is_some(),
        "B1 feeds chamber 2"
    );
}
