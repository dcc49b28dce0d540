//! The manifold network as a component (chapter 3): the valve port flows and the chamber
//! pressures in, the valve port pressures and the flows delivered into the chambers out.
//! Its states are the node pressures (3.2) and the passage flows (3.3).

use super::{oil_stiffness_slope, Component, Jacobian, Port, Signature, State};
use crate::fluid::oil_stiffness;
use crate::fluid::FluidParams;
use crate::manifold::{Circuit, NetworkState, Port as End, MAX_NODES};
use crate::params::LPM;

/// Input ports: Q_A1, Q_B1, Q_A2, Q_B2 (valve v port k at 2v + k), then P1, P2.
pub const CHAMBER_P: usize = 4;
/// Output ports: P_A1, P_B1, P_A2, P_B2, then Q1, Q2.
pub const CHAMBER_Q: usize = 4;

/// The circuit of a mode with the oil in it.
#[derive(Debug, Clone)]
pub struct Network {
    pub circuit: Circuit,
    fluid: FluidParams,
    air: bool,
    tank: f64,
    signature: Signature,
}

impl Network {
    pub fn new(circuit: Circuit, fluid: FluidParams, air: bool, tank: f64) -> Network {
        // 1 Pa on node pressures, 1e-3 L/min on passage flows, as the chambers' 1 Pa
        let states = circuit
            .nodes
            .iter()
            .map(|n| State::new(format!("P_{}", n.name), "Pa", 1.0, 1e6))
            .chain(
                circuit
                    .passages
                    .iter()
                    .map(|p| State::new(format!("Q_{}", p.name), "m3/s", 1e-3 * LPM, 1e-5)),
            )
            .collect();
        let names = ["A1", "B1", "A2", "B2"];
        Network {
            circuit,
            fluid,
            air,
            tank,
            signature: Signature {
                states,
                inputs: names
                    .iter()
                    .map(|n| Port::new(format!("Q_{n}"), "m3/s"))
                    .chain([Port::new("P1", "Pa"), Port::new("P2", "Pa")])
                    .collect(),
                outputs: names
                    .iter()
                    .map(|n| Port::new(format!("P_{n}"), "Pa"))
                    .chain([Port::new("Q1", "m3/s"), Port::new("Q2", "m3/s")])
                    .collect(),
            },
        }
    }

    pub fn n_nodes(&self) -> usize {
        self.circuit.nodes.len()
    }

    /// The network's pressures at state `x` with chamber pressures `chambers`.
    pub fn state<'a>(&self, x: &'a [f64], chambers: [f64; 2]) -> NetworkState<'a> {
        let nn = self.n_nodes();
        NetworkState {
            nodes: &x[..nn],
            flows: &x[nn..],
            chambers,
            tank: self.tank,
        }
    }

    pub fn stiffness(&self, p: f64) -> f64 {
        oil_stiffness(&self.fluid, self.air, p)
    }

    /// Right-hand side for valve port flows `ports` and chamber pressures `chambers`;
    /// returns the flows into the chambers.
    pub fn derivatives_with(
        &self,
        x: &[f64],
        ports: &[[f64; 2]; 2],
        chambers: [f64; 2],
        dx: &mut [f64],
    ) -> [f64; 2] {
        let (dn, df) = dx.split_at_mut(self.n_nodes());
        self.circuit.derivatives(
            &self.state(x, chambers),
            ports,
            |p| self.stiffness(p),
            dn,
            df,
        )
    }

    /// Flows into the nodes and the chambers at state `x` with inputs `u`.
    fn inflows(&self, x: &[f64], u: &[f64]) -> ([f64; MAX_NODES], [f64; 2]) {
        let s = self.state(x, [u[CHAMBER_P], u[CHAMBER_P + 1]]);
        self.circuit.inflows(&s, &[[u[0], u[1]], [u[2], u[3]]])
    }
}

impl Component for Network {
    fn signature(&self) -> &Signature {
        &self.signature
    }

    fn derivatives(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
        let ports = [[u[0], u[1]], [u[2], u[3]]];
        self.derivatives_with(x, &ports, [u[CHAMBER_P], u[CHAMBER_P + 1]], dx);
    }

    fn outputs_at(&self, x: &[f64], u: &[f64], y: &mut [f64]) {
        self.outputs_of(x, u, 0..CHAMBER_Q + 2, y)
    }

    /// The chamber flows are the node balances' by-product.
    fn derivatives_and_outputs(
        &self,
        x: &[f64],
        u: &[f64],
        which: std::ops::Range<usize>,
        dx: &mut [f64],
        y: &mut [f64],
    ) {
        self.outputs_of(x, u, which.start..which.end.min(CHAMBER_Q), y);
        let ports = [[u[0], u[1]], [u[2], u[3]]];
        let q_ch = self.derivatives_with(x, &ports, [u[CHAMBER_P], u[CHAMBER_P + 1]], dx);
        if which.end > CHAMBER_Q {
            y[CHAMBER_Q..CHAMBER_Q + 2].copy_from_slice(&q_ch);
        }
    }

    /// The port pressures need no flow, the chamber flows need the valves'.
    fn outputs_of(&self, x: &[f64], u: &[f64], which: std::ops::Range<usize>, y: &mut [f64]) {
        if which.start < CHAMBER_Q {
            let s = self.state(x, [u[CHAMBER_P], u[CHAMBER_P + 1]]);
            for (v, ports) in self.circuit.valve_ports.iter().enumerate() {
                for (k, port) in ports.iter().enumerate() {
                    y[2 * v + k] = s.pressure(*port);
                }
            }
        }
        if which.end > CHAMBER_Q {
            let (_, q_ch) = self.inflows(x, u);
            y[CHAMBER_Q..CHAMBER_Q + 2].copy_from_slice(&q_ch);
        }
    }

    fn jacobian(&self, x: &[f64], u: &[f64], jac: &mut Jacobian) {
        let nn = self.n_nodes();
        let c = &self.circuit;
        // d(pressure at an end)/d(x or u): a node state, a chamber input, or the tank
        let d_pressure =
            |jac: &mut Jacobian, row: Option<usize>, out: Option<usize>, end: End, w: f64| match (
                end, row, out,
            ) {
                (End::Node(k), Some(r), _) => *jac.fx(r, k) += w,
                (End::Chamber(ch), Some(r), _) => *jac.fu(r, CHAMBER_P + ch) += w,
                (End::Node(k), None, Some(o)) => *jac.yx(o, k) += w,
                (End::Chamber(ch), None, Some(o)) => *jac.yu(o, CHAMBER_P + ch) += w,
                _ => {}
            };
        for (v, ports) in c.valve_ports.iter().enumerate() {
            for (k, port) in ports.iter().enumerate() {
                d_pressure(jac, None, Some(2 * v + k), *port, 1.0);
                // the port flow goes into a chamber's or a node's balance
                match *port {
                    End::Chamber(ch) => *jac.yu(CHAMBER_Q + ch, 2 * v + k) += 1.0,
                    End::Node(n) => {
                        let k_n = self.stiffness(x[n]) / c.nodes[n].volume;
                        *jac.fu(n, 2 * v + k) += k_n;
                    }
                    End::Tank => {}
                }
            }
        }
        for (k, pass) in c.passages.iter().enumerate() {
            let row = nn + k;
            let q = x[row];
            // (3.3) L dQ/dt = P_from - P_to - dp(Q)
            *jac.fx(row, row) = -pass.pressure_drop_slope(q) / pass.inertance;
            d_pressure(jac, Some(row), None, pass.from, 1.0 / pass.inertance);
            d_pressure(jac, Some(row), None, pass.to, -1.0 / pass.inertance);
            for (end, sign) in [(pass.from, -1.0), (pass.to, 1.0)] {
                match end {
                    End::Chamber(ch) => *jac.yx(CHAMBER_Q + ch, row) += sign,
                    End::Node(n) => {
                        *jac.fx(n, row) += sign * self.stiffness(x[n]) / c.nodes[n].volume
                    }
                    End::Tank => {}
                }
            }
        }
        // (3.2) P_n' = beta(P_n)/V_n Q_n: the modulus's slope and the reducers' flow
        let (q_node, _) = self.inflows(x, u);
        for (n, node) in c.nodes.iter().enumerate() {
            let p = x[n];
            *jac.fx(n, n) +=
                oil_stiffness_slope(&self.fluid, self.air, p) / node.volume * q_node[n];
        }
        for r in &c.reducers {
            let n = r.node;
            *jac.fx(n, n) -=
                self.stiffness(x[n]) / c.nodes[n].volume * r.flow_slope(x[n], self.tank);
        }
    }
}
