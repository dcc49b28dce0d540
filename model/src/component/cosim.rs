//! Components as co-simulation units: what a component FMU integrates between two
//! communication points, and the coupling terms its ports hand its neighbours
//! (docs/cosim.md). The physics of the coupling lives here, with the components; the FMUs
//! only declare variables onto these inputs and outputs.
//!
//! Over a step the inputs are held. Where holding one would leave a stiff loop explicit,
//! the neighbour hands over its element as plain signals and the step carries it:
//! - the valves' port sensitivities dQ/dP let the manifold's port flows follow the port
//!   pressures, Q + dQ/dP (P - P0);
//! - the chambers' displaced flow, volume and modulus let the manifold carry the chamber
//!   pressures, P' = beta/V (Q - Q_displaced) (4.1);
//! - the passages' driving pressure, inertance and the node behind them let the actuator
//!   carry the chamber flows, Q' = (P_drive - P)/L (3.3), P_drive' = beta/V (Q_feed - Q) (3.2).

use super::actuator::{ActuatorComponent, F_EXT, P1, P2, Q1, Q2, V, Y};
use super::network::{Network, CHAMBER_P};
use super::valve::{self, Valve};
use super::{Component, Jacobian, State};
use crate::manifold::Port as End;

/// The right-hand side of one co-simulation step over the unit's states followed by the
/// states the step carries, with the inputs held.
pub type StepRhs<'a> = Box<dyn Fn(&[f64], &mut [f64]) + 'a>;

/// What one step integrates: its initial state, the states' declarations (the persistent
/// ones first), and the right-hand side.
pub struct StepSystem<'a> {
    pub x: Vec<f64>,
    pub states: Vec<State>,
    pub rhs: StepRhs<'a>,
}

/// A component FMU's model: states, inputs and outputs by position.
pub trait CosimUnit: std::fmt::Debug + Send + Sync {
    /// The persistent states.
    fn states(&self) -> &[State];
    /// The rest state for inputs `u`.
    fn initial_state(&self, u: &[f64]) -> Vec<f64>;
    /// All outputs, coupling terms included.
    fn outputs(&self, x: &[f64], u: &[f64], y: &mut [f64]);
    /// The step from state `x` with inputs `u` held.
    fn step<'a>(&'a self, x: &[f64], u: &'a [f64]) -> StepSystem<'a>;
}

/// A state of this unit, checked before it is restored from bytes: the right size,
/// finite, absolute pressures (states in Pa) not negative.
pub fn check_state(unit: &dyn CosimUnit, x: &[f64]) -> Result<(), String> {
    let states = unit.states();
    if x.len() != states.len() {
        return Err(format!("a state of this model has {} values", states.len()));
    }
    let bad = x
        .iter()
        .zip(states)
        .any(|(v, s)| !v.is_finite() || (s.unit == "Pa" && *v < 0.0));
    if bad {
        return Err("the state holds a non-finite value or a negative absolute pressure".into());
    }
    Ok(())
}

/// A servovalve. Inputs: u, P_P, P_T, P_A, P_B. Outputs: Q_A, Q_B, x_s, and the port
/// sensitivities dQ_A/dP_A, dQ_B/dP_B from the exact Jacobian.
#[derive(Debug)]
pub struct ValveUnit(pub Valve);

impl CosimUnit for ValveUnit {
    fn states(&self) -> &[State] {
        self.0.states()
    }
    fn initial_state(&self, u: &[f64]) -> Vec<f64> {
        let mut x = vec![0.0; self.0.states().len()];
        self.0.model().initial_state(u[valve::U], &mut x);
        x
    }
    fn outputs(&self, x: &[f64], u: &[f64], y: &mut [f64]) {
        let mut q = [0.0; 4];
        self.0.outputs_at(x, u, &mut q);
        let mut jac = Jacobian::zeros(x.len(), 5, 4);
        self.0.jacobian(x, u, &mut jac);
        y[..5].copy_from_slice(&[
            q[valve::Q_A],
            q[valve::Q_B],
            q[valve::X_S],
            jac.yu[valve::Q_A * 5 + valve::P_A],
            jac.yu[valve::Q_B * 5 + valve::P_B],
        ]);
    }
    fn step<'a>(&'a self, x: &[f64], u: &'a [f64]) -> StepSystem<'a> {
        StepSystem {
            x: x.to_vec(),
            states: self.0.states().to_vec(),
            rhs: Box::new(move |x, dx| self.0.derivatives(x, u, dx)),
        }
    }
}

/// Inputs of the manifold unit after the network's six: the valves' sensitivities,
/// then the chambers' displaced flows, volumes and moduli.
pub const SENSITIVITIES: usize = 6;
pub const CHAMBERS: usize = 10;

/// The manifold network. Inputs: Q_A1, Q_B1, Q_A2, Q_B2, P1, P2, the four dQ/dP, then
/// Q1_displaced, Q2_displaced, V1, V2, beta1, beta2. Outputs: P_A1, P_B1, P_A2, P_B2, Q1,
/// Q2, then P1_drive, P2_drive, L1, L2, V1_drive, V2_drive, beta1_drive, beta2_drive,
/// Q1_feed, Q2_feed.
#[derive(Debug)]
pub struct NetworkUnit(pub Network);

impl NetworkUnit {
    /// The port flows over a step: each follows its port's pressure to first order from
    /// the step's start, Q + dQ/dP (P - P0) (all dQ/dP zero: held).
    fn port_flows(&self, x: &[f64], u: &[f64], chambers: [f64; 2], p0: &[f64; 4]) -> [[f64; 2]; 2] {
        let s = self.0.state(x, chambers);
        let ports = &self.0.circuit.valve_ports;
        let q = |k: usize| u[k] + u[SENSITIVITIES + k] * (s.pressure(ports[k / 2][k % 2]) - p0[k]);
        [[q(0), q(1)], [q(2), q(3)]]
    }
}

impl CosimUnit for NetworkUnit {
    fn states(&self) -> &[State] {
        self.0.states()
    }

    /// Nodes between the two chamber pressures, passages at rest.
    fn initial_state(&self, u: &[f64]) -> Vec<f64> {
        let mid = 0.5 * (u[CHAMBER_P] + u[CHAMBER_P + 1]);
        let nn = self.0.n_nodes();
        (0..self.0.states().len())
            .map(|k| if k < nn { mid } else { 0.0 })
            .collect()
    }

    fn outputs(&self, x: &[f64], u: &[f64], y: &mut [f64]) {
        let net = &self.0;
        let c = &net.circuit;
        let nn = net.n_nodes();
        let chambers = [u[CHAMBER_P], u[CHAMBER_P + 1]];
        let mut dx = vec![0.0; x.len()];
        let ports = [[u[0], u[1]], [u[2], u[3]]];
        let q = net.derivatives_with(x, &ports, chambers, &mut dx);
        net.outputs_at(x, u, &mut y[..6]);
        // The passages at each chamber as one driving pressure behind one inertance: a
        // passage flow counts into a chamber it ends at and out of one it starts from,
        // and either way its rate falls by 1/inertance per pascal of chamber pressure;
        // in parallel, L = 1 / sum(1/L_k) and P_drive = P + L dQ/dt (3.3). With a single
        // passage (every mode of the network: N-V), the node behind it goes along: its
        // pressure follows the passage flow within a step, p' = beta/V (Q_feed - Q) (3.2),
        // stiffer than the chamber by its smaller volume, so it cannot be held.
        let (mut rate, mut admittance, mut count) = ([0.0; 2], [0.0; 2], [0; 2]);
        let mut node = [None; 2];
        for (pass, d) in c.passages.iter().zip(&dx[nn..]) {
            for (end, other, sign) in [(pass.to, pass.from, 1.0), (pass.from, pass.to, -1.0)] {
                if let End::Chamber(ch) = end {
                    rate[ch] += sign * d;
                    admittance[ch] += 1.0 / pass.inertance;
                    count[ch] += 1;
                    if let End::Node(k) = other {
                        node[ch] = Some(k);
                    }
                }
            }
        }
        let l = admittance.map(|a| if a > 0.0 { 1.0 / a } else { 0.0 });
        // (volume, bulk modulus, flow fed into the node by all but the chamber's passage)
        let behind: [(f64, f64, f64); 2] = std::array::from_fn(|ch| match node[ch] {
            Some(k) if count[ch] == 1 => {
                let (v, b) = (c.nodes[k].volume, net.stiffness(x[k]));
                (v, b, dx[k] * v / b + q[ch])
            }
            _ => (0.0, 0.0, 0.0),
        });
        for ch in 0..2 {
            y[6 + ch] = chambers[ch] + l[ch] * rate[ch];
            y[8 + ch] = l[ch];
            y[10 + ch] = behind[ch].0;
            y[12 + ch] = behind[ch].1;
            y[14 + ch] = behind[ch].2;
        }
    }

    /// With the actuator's chamber terms connected (V_i > 0), the chamber pressures
    /// become states of the step, P_i' = beta_i/V_i (Q_i - Q_displaced,i) (4.1): the
    /// passage flows then meet the pressure their own inflow builds instead of a held
    /// one, which closes the passage/chamber loop (near 780 Hz) within the step.
    fn step<'a>(&'a self, x: &[f64], u: &'a [f64]) -> StepSystem<'a> {
        let n = x.len();
        let held = [u[CHAMBER_P], u[CHAMBER_P + 1]];
        let s = self.0.state(x, held);
        let ports = &self.0.circuit.valve_ports;
        let p0: [f64; 4] = std::array::from_fn(|k| s.pressure(ports[k / 2][k % 2]));
        let [qd1, qd2, v1, v2, b1, b2] = std::array::from_fn(|k| u[CHAMBERS + k]);
        let stiffness = |b: f64, v: f64| if v > 0.0 { b / v } else { 0.0 };
        let (k1, k2) = (stiffness(b1, v1), stiffness(b2, v2));
        let carried = v1 > 0.0 || v2 > 0.0;
        let mut states = self.0.states().to_vec();
        let mut x0 = x.to_vec();
        if carried {
            x0.extend(held);
            states.extend(["P1", "P2"].map(|name| State::new(name, "Pa", 1.0, 1e6)));
        }
        let rhs: StepRhs<'a> = Box::new(move |x, dx| {
            let chambers = if carried { [x[n], x[n + 1]] } else { held };
            let flows = self.port_flows(&x[..n], u, chambers, &p0);
            let q = self
                .0
                .derivatives_with(&x[..n], &flows, chambers, &mut dx[..n]);
            if carried {
                dx[n] = k1 * (q[0] - qd1);
                dx[n + 1] = k2 * (q[1] - qd2);
            }
        });
        StepSystem { x: x0, states, rhs }
    }
}

/// Inputs of the actuator unit after Q1, Q2, F_ext: the passages' P1_drive, P2_drive,
/// L1, L2, V1_drive, V2_drive, beta1_drive, beta2_drive, Q1_feed, Q2_feed.
pub const PASSAGES: usize = 3;

/// The actuator. Inputs: Q1, Q2, F_ext, then the passage terms ([`PASSAGES`]).
/// Outputs: P1, P2, y, v, a, then Q1_displaced, Q2_displaced, V1, V2, beta1, beta2.
#[derive(Debug)]
pub struct ActuatorUnit {
    pub component: ActuatorComponent,
    /// Rest position (m) and supply pressure (Pa) the rest state is taken at.
    pub y0: f64,
    pub supply: f64,
    pub tank: f64,
}

impl CosimUnit for ActuatorUnit {
    fn states(&self) -> &[State] {
        self.component.states()
    }

    /// At rest at y0, the chambers at half supply pressure, split to carry the weight.
    fn initial_state(&self, _u: &[f64]) -> Vec<f64> {
        let [p1, p2] = self
            .component
            .actuator
            .rest_pressures(self.supply, self.tank);
        vec![self.y0, 0.0, p1, p2]
    }

    fn outputs(&self, x: &[f64], u: &[f64], y: &mut [f64]) {
        let mut dx = [0.0; 4];
        self.component.derivatives(x, &u[..3], &mut dx);
        y[..5].copy_from_slice(&[x[P1], x[P2], x[Y], x[V], dx[V]]);
        y[5..11].copy_from_slice(&self.component.chamber_port(x));
    }

    /// With the manifold's passages connected (L_i > 0), the chamber flows and the
    /// pressures of the nodes behind them become states of the step,
    ///   Q_i' = (P_i,drive - P_i) / L_i,   P_i,drive' = beta_i,drive/V_i,drive (Q_i,feed - Q_i),
    /// so the passage answers the chamber pressure within the step.
    fn step<'a>(&'a self, x: &[f64], u: &'a [f64]) -> StepSystem<'a> {
        let p = |k: usize| u[PASSAGES + k];
        let section = [(p(2), p(4), p(6), p(8)), (p(3), p(5), p(7), p(9))];
        let carried = p(2) > 0.0 || p(3) > 0.0;
        let mut states = self.component.states().to_vec();
        let mut x0 = x.to_vec();
        if carried {
            x0.extend([u[Q1], u[Q2], p(0), p(1)]);
            states.extend([
                ActuatorComponent::flow_state("Q1"),
                ActuatorComponent::flow_state("Q2"),
                State::new("P1_drive", "Pa", 1.0, 1e6),
                State::new("P2_drive", "Pa", 1.0, 1e6),
            ]);
        }
        let rhs: StepRhs<'a> = Box::new(move |x, dx| {
            if !carried {
                self.component.derivatives(x, &u[..3], dx);
                return;
            }
            self.component.derivatives(x, &[x[4], x[5], u[F_EXT]], dx);
            for (i, &(l, v, b, feed)) in section.iter().enumerate() {
                let (q, drive) = (x[4 + i], x[6 + i]);
                (dx[4 + i], dx[6 + i]) = if l > 0.0 {
                    let dd = if v > 0.0 { b / v * (feed - q) } else { 0.0 };
                    ((drive - x[2 + i]) / l, dd)
                } else {
                    (0.0, 0.0)
                };
            }
        });
        StepSystem { x: x0, states, rhs }
    }
}
