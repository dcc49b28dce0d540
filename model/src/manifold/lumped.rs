//! The lumped figures of the network: Table 3.3's oil volume joined to each chamber and
//! Table 3.4's equivalent fluid mass on the piston (3.12)-(3.16), found by walking the
//! full network of a mode.

use super::{Circuit, ManifoldConfig, Port};
use crate::params::Mode;

/// The driven valve ports of a mode that push the piston flow into each chamber, with the
/// share of the chamber flow each carries (mode 2: the two valves split it equally, the
/// assumption of Table 3.4).
fn driven_ports(mode: Mode) -> Vec<(usize, usize, usize, f64)> {
    // (valve, port 0=A/1=B, chamber, share)
    match mode {
        Mode::FourWaySingle => vec![(0, 0, 0, 1.0), (0, 1, 1, 1.0)],
        Mode::FourWayParallel => vec![
            (0, 0, 0, 0.5),
            (1, 1, 0, 0.5),
            (1, 0, 1, 0.5),
            (0, 1, 1, 0.5),
        ],
        Mode::ThreeWay => vec![(0, 0, 0, 1.0), (1, 0, 1, 1.0)],
    }
}

/// The passages on the way from a node to a chamber, found by walking the network (a
/// tree between the two bifurcations).
pub(super) fn path_to_chamber(c: &Circuit, start: Port, chamber: usize) -> Option<Vec<usize>> {
    fn walk(c: &Circuit, at: Port, target: Port, used: &mut Vec<usize>) -> bool {
        if at == target {
            return true;
        }
        for (k, p) in c.passages.iter().enumerate() {
            if used.contains(&k) {
                continue;
            }
            let next = if p.from == at {
                p.to
            } else if p.to == at {
                p.from
            } else {
                continue;
            };
            used.push(k);
            if walk(c, next, target, used) {
                return true;
            }
            used.pop();
        }
        false
    }
    let mut used = Vec::new();
    walk(c, start, Port::Chamber(chamber), &mut used).then_some(used)
}

/// The full network with unit scales, used for the lumped figures.
pub(super) fn reference_network(mode: Mode, density: f64) -> Circuit {
    Circuit::network(
        mode,
        &ManifoldConfig {
            volume: true,
            inertia: true,
            losses: false,
            volume_scale: 1.0,
            inertia_scale: 1.0,
            loss_scale: 0.0,
            density,
            viscosity: 0.0,
            // the figures derived from it are per unit area
            piston_area: 1.0,
        },
    )
}

/// Table 3.3: oil volume hydraulically joined to each chamber, i.e. every passage volume
/// in the chamber's connected part of the network (valves and reducers cut it).
pub fn added_volume(mode: Mode) -> [f64; 2] {
    let net = reference_network(mode, 1.0);
    let mut out = [0.0; 2];
    for (ch, total) in out.iter_mut().enumerate() {
        // passages reachable from the chamber through passages only
        let mut reach = vec![Port::Chamber(ch)];
        let mut seen = vec![false; net.passages.len()];
        while let Some(at) = reach.pop() {
            for (k, p) in net.passages.iter().enumerate() {
                if seen[k] || (p.from != at && p.to != at) {
                    continue;
                }
                seen[k] = true;
                *total += p.kind.volume();
                reach.push(if p.from == at { p.to } else { p.from });
            }
        }
    }
    out
}

/// Table 3.4: equivalent fluid mass referred to the piston (3.12)-(3.16),
/// A^2 * sum(lambda_k^2 * rho l_k / a_k), lambda_k the share of the chamber flow in
/// passage k. Returned per unit piston area squared times area^2 (kg).
pub fn equivalent_mass_per_area2(mode: Mode, density: f64) -> f64 {
    let net = reference_network(mode, density);
    let mut lambda = vec![0.0; net.passages.len()];
    for (valve, port, chamber, share) in driven_ports(mode) {
        let start = net.valve_ports[valve][port];
        if let Some(path) = path_to_chamber(&net, start, chamber) {
            for k in path {
                lambda[k] += share; // (3.14) branch flow over total flow
            }
        }
    }
    net.passages
        .iter()
        .zip(&lambda)
        .map(|(p, l)| l * l * p.inertance) // (3.16) per A^2
        .sum()
}

/// Table 3.4: the fluid mass referred to a piston of area `area` (m2).
pub fn equivalent_mass(mode: Mode, density: f64, area: f64) -> f64 {
    area * area * equivalent_mass_per_area2(mode, density)
}
