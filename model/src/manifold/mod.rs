//! The manifold between the servovalves and the actuator (chapter 3, Fig. 3.2).
//!
//! Each passage Ai-Ni, Ni-Vi, Bi-Ci, Ci-Nj is a C-R-I-C element (Fig. 3.3a): half its oil
//! volume at each end (3.2), a nonlinear resistance (3.5)-(3.7) and an inertance (3.3).
//! Bifurcations N1, N2 are nodes; the solenoid valves V1, V2 are ideal switches (3.4)
//! that join Ci to the passage Ci-Nj (on, modes 1-2) or to the flow reducer to tank (off,
//! mode 3, where Ci-Nj becomes a dead leg hanging from Nj).
//!
//! # Passage geometry
//! The thesis gives lumped figures, not drawings, so the geometry is chosen to make those
//! figures come out of this network:
//! - volumes: Table 3.3 is the oil volume hydraulically joined to each chamber. In modes 1-2
//!   that is Ai-Ni + Ni-Vi + Cj-Ni + Bj-Cj = 1.0041e-4 m3, in mode 3 (Bj-Cj now drains to
//!   tank) Ai-Ni + Ni-Vi + Cj-Ni = 7.9754e-5 m3. Ai-Ni is about 2e-6 m3 (section 3.2); Ci-Nj
//!   is taken 3e-5 m3 with the mean section of Table 3.1 (150 mm2, 200 mm long); the
//!   tables then fix Bj-Cj = 2.0656e-5 m3 and Ni-Vi = 4.7754e-5 m3.
//! - inertances I = rho*l/a: Table 3.4 is A^2 * sum(lambda_k^2 * I_k) over the passages the
//!   piston flow crosses (3.16), with lambda = 1/2 in mode 2. The three modes give three
//!   equations in I_AN, I_NV and I_CN + I_BC; with I_CN from the chosen Ci-Nj geometry they
//!   fix every inertance, hence every length and section (rho = 862 kg/m3).
//! - losses: Table 3.2 (passage C1-N2) is fitted by dp = K_t Q|Q| + K_l Q to 1 %; K_l is
//!   the Hagen-Poiseuille term of (3.7) for the passage's length and section, K_t gives a
//!   global singular-loss coefficient zeta = 7.32 (3.5)-(3.6), used for every passage since
//!   all are drilled channels with two right-angle junctions like C1-N2.

use crate::fluid::signed_sqrt;
use crate::params::{Mode, BAR};

mod lumped;
#[cfg(test)]
mod tests;

pub use lumped::{added_volume, equivalent_mass, equivalent_mass_per_area2};

/// A passage family of Fig. 3.2 (the same geometry on both sides of the bench).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PassageKind {
    /// Servovalve port A to bifurcation N.
    AN,
    /// Bifurcation N to actuator port V.
    NV,
    /// Servovalve port B to solenoid valve C.
    BC,
    /// Solenoid valve C to the other side's bifurcation N.
    CN,
}

/// Length (m) and section (m2) of a passage family; see the module notes for how.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassageGeometry {
    pub length: f64,
    pub area: f64,
}

impl PassageKind {
    pub fn geometry(self) -> PassageGeometry {
        match self {
            PassageKind::AN => PassageGeometry {
                length: 0.057179,
                area: 3.497767e-5,
            },
            PassageKind::NV => PassageGeometry {
                length: 0.166974,
                area: 2.859958e-4,
            },
            PassageKind::BC => PassageGeometry {
                length: 0.201318,
                area: 1.026038e-4,
            },
            PassageKind::CN => PassageGeometry {
                length: 0.200,
                area: 1.5e-4,
            },
        }
    }
    pub fn volume(self) -> f64 {
        let g = self.geometry();
        g.length * g.area
    }
}

/// Global singular-loss coefficient of a passage (3.6), fitted to Table 3.2.
pub const PASSAGE_LOSS_COEFFICIENT: f64 = 7.32;

/// Flow reducer DR1/DR2 from Ci to tank in mode 3 (m3/s/sqrt(Pa)). Not printed; sized to
/// pass 5 L/min under 100 bar, a quarter of a valve's rated flow, so that a B port
/// opened to supply wastes little oil while one opened to tank drains freely.
pub const FLOW_REDUCER_COEFFICIENT: f64 = 5.0e-3 / 60.0 / 3_162.277_660_168_379_5; // sqrt(100 bar)

/// Laminar core of the flow reducer orifice (Pa).
const REDUCER_LAMINAR_TRANSITION: f64 = 0.5 * BAR;

/// Where a valve port or a passage end is connected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Port {
    /// Actuator chamber 0 (chamber 1 of the thesis) or 1.
    Chamber(usize),
    /// Internal node of the manifold network.
    Node(usize),
    Tank,
}

/// An internal node: a bifurcation or a passage end, with the oil volume attached to it.
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    pub name: String,
    pub volume: f64,
}

/// One passage as a network branch with a flow state.
#[derive(Debug, Clone, PartialEq)]
pub struct Passage {
    pub name: String,
    pub kind: PassageKind,
    pub side: usize,
    pub from: Port,
    pub to: Port,
    /// rho*l/a (Pa.s2/m3), (3.3)
    pub inertance: f64,
    /// dp = turbulent*Q|Q| + laminar*Q (Pa), (3.5)-(3.7)
    pub turbulent: f64,
    pub laminar: f64,
}

impl Passage {
    /// (3.5)-(3.7) pressure drop along the passage for flow q (from -> to).
    pub fn pressure_drop(&self, q: f64) -> f64 {
        self.turbulent * q * q.abs() + self.laminar * q
    }

    /// d(pressure_drop)/dq.
    pub fn pressure_drop_slope(&self, q: f64) -> f64 {
        2.0 * self.turbulent * q.abs() + self.laminar
    }
}

/// Flow reducer from a node to tank (mode 3).
#[derive(Debug, Clone, PartialEq)]
pub struct Reducer {
    pub node: usize,
    pub coefficient: f64,
}

impl Reducer {
    pub fn flow(&self, p_node: f64, p_tank: f64) -> f64 {
        self.coefficient * signed_sqrt(p_node - p_tank, REDUCER_LAMINAR_TRANSITION)
    }

    /// d(flow)/d(p_node).
    pub fn flow_slope(&self, p_node: f64, p_tank: f64) -> f64 {
        self.coefficient
            * crate::fluid::signed_sqrt_slope(p_node - p_tank, REDUCER_LAMINAR_TRANSITION)
    }
}

/// The hydraulic circuit between valves and chambers for one mode and set of effects.
#[derive(Debug, Clone, PartialEq)]
pub struct Circuit {
    pub nodes: Vec<Node>,
    pub passages: Vec<Passage>,
    pub reducers: Vec<Reducer>,
    /// `valve_ports[v] = [port A, port B]` of servovalve v.
    pub valve_ports: [[Port; 2]; 2],
    /// Oil volume merged into each chamber (m3).
    pub chamber_volume: [f64; 2],
    /// Fluid mass added to the piston when the inertia is lumped (kg).
    pub added_mass: f64,
}

/// How the manifold is represented.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ManifoldConfig {
    pub volume: bool,
    pub inertia: bool,
    pub losses: bool,
    pub volume_scale: f64,
    pub inertia_scale: f64,
    pub loss_scale: f64,
    /// Oil density (kg/m3) and dynamic viscosity (Pa.s) for inertances and losses.
    pub density: f64,
    pub viscosity: f64,
    /// Piston area (m2) the lumped fluid mass is referred to (3.16).
    pub piston_area: f64,
}

/// Passages of the network, by kind and side (0 or 1), with their end points before
/// nodes are numbered. Returns (kind, side, from, to) with node names.
fn topology(mode: Mode) -> Vec<(PassageKind, usize, End, End)> {
    let mut t = Vec::new();
    for i in 0..2 {
        let j = 1 - i;
        t.push((
            PassageKind::AN,
            i,
            End::Named(format!("A{}", i + 1)),
            End::Named(format!("N{}", i + 1)),
        ));
        t.push((
            PassageKind::NV,
            i,
            End::Named(format!("N{}", i + 1)),
            End::Chamber(i),
        ));
        t.push((
            PassageKind::BC,
            i,
            End::Named(format!("B{}", i + 1)),
            End::Named(format!("C{}", i + 1)),
        ));
        // (3.4) the solenoid valve joins Ci to Ci-Nj when on; off, Ci-Nj is a dead leg
        let c_end = if mode.solenoids_on() {
            format!("C{}", i + 1)
        } else {
            format!("D{}", i + 1)
        };
        t.push((
            PassageKind::CN,
            i,
            End::Named(c_end),
            End::Named(format!("N{}", j + 1)),
        ));
    }
    t
}

#[derive(Debug, Clone, PartialEq)]
enum End {
    Named(String),
    Chamber(usize),
}

/// Direct connection of valve ports when the manifold is not modelled as a network.
fn direct_ports(mode: Mode) -> [[Port; 2]; 2] {
    if mode.solenoids_on() {
        // 4-way: A1 and B2 feed chamber 1, A2 and B1 chamber 2 (Fig. 3.2)
        [
            [Port::Chamber(0), Port::Chamber(1)],
            [Port::Chamber(1), Port::Chamber(0)],
        ]
    } else {
        [
            [Port::Chamber(0), Port::Tank],
            [Port::Chamber(1), Port::Tank],
        ]
    }
}

impl Circuit {
    /// The circuit a parameter set asks for (mode, manifold effects and scales, oil).
    pub fn from_params(p: &crate::params::Params) -> Circuit {
        use crate::effects::Effect;
        let fluid = p.fluid_in_use();
        Circuit::new(
            p.mode,
            &ManifoldConfig {
                volume: p.has(Effect::ManifoldVolume),
                inertia: p.has(Effect::ManifoldInertia),
                losses: p.has(Effect::ManifoldLosses),
                volume_scale: p.manifold.volume_scale,
                inertia_scale: p.manifold.inertia_scale,
                loss_scale: p.manifold.loss_scale,
                density: fluid.density,
                viscosity: fluid
                    .dynamic_viscosity(fluid.temperature, crate::fluid::ATMOSPHERIC_PRESSURE),
                piston_area: p.actuator.area,
            },
        )
    }

    /// Build the circuit. With both volume and inertia on, the full C-R-I-C network; with
    /// only one of them, its lumped equivalent (Table 3.3 volume added to each chamber, or
    /// Table 3.4 mass added to the piston), as the thesis does in sections 3.4-3.5.
    pub fn new(mode: Mode, c: &ManifoldConfig) -> Circuit {
        if c.volume && c.inertia {
            return Self::network(mode, c);
        }
        let mut circuit = Circuit {
            nodes: vec![],
            passages: vec![],
            reducers: vec![],
            valve_ports: direct_ports(mode),
            chamber_volume: [0.0; 2],
            added_mass: 0.0,
        };
        if c.volume {
            circuit.chamber_volume = added_volume(mode).map(|v| v * c.volume_scale);
        }
        if c.inertia {
            circuit.added_mass = equivalent_mass(mode, c.density, c.piston_area) * c.inertia_scale;
        }
        circuit
    }

    fn network(mode: Mode, c: &ManifoldConfig) -> Circuit {
        let mut nodes: Vec<Node> = Vec::new();
        let mut chamber_volume = [0.0; 2];
        let node_of = |name: &str, nodes: &mut Vec<Node>| -> usize {
            match nodes.iter().position(|n| n.name == name) {
                Some(k) => k,
                None => {
                    nodes.push(Node {
                        name: name.to_string(),
                        volume: 0.0,
                    });
                    nodes.len() - 1
                }
            }
        };
        let mut passages = Vec::new();
        for (kind, side, from, to) in topology(mode) {
            let g = kind.geometry();
            let half = 0.5 * kind.volume() * c.volume_scale;
            let mut resolve = |end: &End, nodes: &mut Vec<Node>| match end {
                End::Named(name) => {
                    let k = node_of(name, nodes);
                    nodes[k].volume += half; // (3.2) half the passage volume at each end
                    Port::Node(k)
                }
                End::Chamber(ch) => {
                    chamber_volume[*ch] += half;
                    Port::Chamber(*ch)
                }
            };
            let from = resolve(&from, &mut nodes);
            let to = resolve(&to, &mut nodes);
            let loss = if c.losses { c.loss_scale } else { 0.0 };
            passages.push(Passage {
                name: format!("{:?}{}", kind, side + 1),
                kind,
                side,
                from,
                to,
                inertance: c.density * g.length / g.area * c.inertia_scale, // (3.3)
                // (3.5) singular losses, zeta*rho/2*(Q/A)^2
                turbulent: loss * PASSAGE_LOSS_COEFFICIENT * c.density / (2.0 * g.area * g.area),
                // (3.7) friction losses, Hagen-Poiseuille 128 mu l Q/(pi d^4) = 8 pi mu l Q/A^2
                laminar: loss * 8.0 * std::f64::consts::PI * c.viscosity * g.length
                    / (g.area * g.area),
            });
        }
        let find = |name: &str| nodes.iter().position(|n| n.name == name).map(Port::Node);
        let port = |name: String| find(&name).expect("every valve port is a node of the network");
        let valve_ports = [
            [port("A1".into()), port("B1".into())],
            [port("A2".into()), port("B2".into())],
        ];
        let reducers = if mode.solenoids_on() {
            vec![]
        } else {
            (1..=2)
                .map(|i| Reducer {
                    node: nodes
                        .iter()
                        .position(|n| n.name == format!("C{i}"))
                        .expect("C node"),
                    coefficient: FLOW_REDUCER_COEFFICIENT,
                })
                .collect()
        };
        Circuit {
            nodes,
            passages,
            reducers,
            valve_ports,
            chamber_volume,
            added_mass: 0.0,
        }
    }
}

/// Pressures on the manifold's boundary and inside it, for evaluating the network.
#[derive(Debug, Clone, Copy)]
pub struct NetworkState<'a> {
    /// Pressures of the internal nodes (Pa).
    pub nodes: &'a [f64],
    /// Flows of the passages, from -> to (m3/s).
    pub flows: &'a [f64],
    /// Chamber pressures (Pa).
    pub chambers: [f64; 2],
    pub tank: f64,
}

impl NetworkState<'_> {
    pub fn pressure(&self, port: Port) -> f64 {
        match port {
            Port::Chamber(c) => self.chambers[c],
            Port::Node(k) => self.nodes[k],
            Port::Tank => self.tank,
        }
    }
}

/// Largest number of internal nodes of any mode (mode 3: A, B, C, D and N on each side).
pub const MAX_NODES: usize = 10;

impl Circuit {
    /// Flows into the nodes and the chambers for the given valve port flows: the port
    /// flows, the passage flows (from -> to) and the flow reducers to tank.
    pub fn inflows(
        &self,
        s: &NetworkState,
        port_flows: &[[f64; 2]; 2],
    ) -> ([f64; MAX_NODES], [f64; 2]) {
        let mut q_node = [0.0; MAX_NODES];
        let mut q_ch = [0.0; 2];
        let mut add = |port: Port, q: f64| match port {
            Port::Chamber(c) => q_ch[c] += q,
            Port::Node(k) => q_node[k] += q,
            Port::Tank => {}
        };
        for (ports, flows) in self.valve_ports.iter().zip(port_flows) {
            for (port, q) in ports.iter().zip(flows) {
                add(*port, *q);
            }
        }
        for (pass, q) in self.passages.iter().zip(s.flows) {
            add(pass.from, -q);
            add(pass.to, *q);
        }
        for r in &self.reducers {
            q_node[r.node] -= r.flow(s.nodes[r.node], s.tank);
        }
        (q_node, q_ch)
    }

    /// Right-hand side of the network: (3.2) node pressures and (3.3) passage flows, for
    /// the given valve port flows. `bulk(p)` is the oil's effective bulk modulus. Returns
    /// the flows delivered into the chambers.
    pub fn derivatives(
        &self,
        s: &NetworkState,
        port_flows: &[[f64; 2]; 2],
        bulk: impl Fn(f64) -> f64,
        d_nodes: &mut [f64],
        d_flows: &mut [f64],
    ) -> [f64; 2] {
        let (q_node, q_ch) = self.inflows(s, port_flows);
        for (k, pass) in self.passages.iter().enumerate() {
            // (3.3) fluid inertia driven by the pressure difference less the losses
            d_flows[k] =
                (s.pressure(pass.from) - s.pressure(pass.to) - pass.pressure_drop(s.flows[k]))
                    / pass.inertance;
        }
        for (k, node) in self.nodes.iter().enumerate() {
            // (3.2) compressibility of the node's share of passage volume
            d_nodes[k] = bulk(s.nodes[k]) / node.volume * q_node[k];
        }
        q_ch
    }
}
