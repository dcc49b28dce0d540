//! The assembled bench: SV1, SV2, manifold and actuator between supply and tank, in one
//! state vector for one stiff solver.
//!
//! State layout: `[y, v, P1, P2 | SV1 states | SV2 states | node pressures | passage flows]`,
//! the blocks of a [`Composition`] of the actuator, the two valves and the manifold.

use std::sync::Arc;

use crate::actuator::Actuator;
use crate::component::actuator::{self, ActuatorComponent};
use crate::component::network::{self, Network};
use crate::component::valve::{self, Valve};
use crate::component::{self, Component, Composition, Source};
use crate::effects::Effect;
use crate::manifold::{Circuit, Port};
use crate::params::{Mode, ParamError, Params};
use crate::servovalve::{self, Servovalve};
use crate::solver::adaptive::{Memory, Workspace};
use crate::solver::jacobian::{Colouring, Pattern};
use crate::solver::{self, Carry, SolverError, SolverStats, Tolerances};

/// Inputs held constant over one integration interval.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Inputs {
    /// Servovalve commands (V).
    pub u1: f64,
    pub u2: f64,
    /// External force on the rod (N), opposing positive y.
    pub f_ext: f64,
}

/// Everything the bench shows at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Outputs {
    pub y: f64,
    pub v: f64,
    pub a: f64,
    pub p1: f64,
    pub p2: f64,
    /// Pressures at the servovalve ports.
    pub p_a1: f64,
    pub p_b1: f64,
    pub p_a2: f64,
    pub p_b2: f64,
    /// Flows leaving the servovalve ports.
    pub q_a1: f64,
    pub q_b1: f64,
    pub q_a2: f64,
    pub q_b2: f64,
    /// Flows from the manifold into the chambers.
    pub q1: f64,
    pub q2: f64,
    /// Flow both servovalves draw from the supply (m3/s).
    pub q_supply: f64,
    /// Spool positions (m).
    pub x_s1: f64,
    pub x_s2: f64,
    pub friction: f64,
}

/// Indices into the state vector.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Layout {
    sv: [usize; 2],
    nodes: usize,
    passages: usize,
    len: usize,
}

const Y: usize = 0;
const V: usize = 1;
const P1: usize = 2;

/// The blocks of the composition, in the order of their states.
const ACT: usize = 0;
const SV: [usize; 2] = [1, 2];
const NET: usize = 3;

/// The bench model: the components its parameters ask for, joined port to port.
#[derive(Debug)]
pub struct Bench {
    params: Params,
    valves: [Arc<dyn Servovalve>; 2],
    circuit: Circuit,
    actuator: Actuator,
    system: Composition,
    layout: Layout,
}

impl Bench {
    pub fn new(params: &Params) -> Result<Bench, ParamError> {
        params.validate()?;
        let p = params;
        let fluid = p.fluid_in_use();
        let air = p.has(Effect::EntrainedAir);
        let valves: [Arc<dyn Servovalve>; 2] = [
            servovalve::build(&p.sv1, p).into(),
            servovalve::build(p.sv2_effective(), p).into(),
        ];
        let circuit = Circuit::from_params(p);
        let actuator = Actuator::from_params(p, circuit.chamber_volume, circuit.added_mass);
        let out = |block: usize, port: usize| Source::Output { block, port };
        // Mode 1 drives the actuator with SV1 alone: SV2 stays connected, at null.
        let command = |k: usize| match (p.mode, k) {
            (Mode::FourWaySingle, 1) => Source::Constant(0.0),
            _ => Source::External(k),
        };
        let valve_block = |k: usize| -> (Box<dyn Component>, Vec<Source>) {
            (
                Box::new(Valve::new(valves[k].clone(), &format!("{}", k + 1))),
                vec![
                    command(k),
                    Source::Constant(p.supply_pressure),
                    Source::Constant(p.tank_pressure),
                    out(NET, 2 * k),
                    out(NET, 2 * k + 1),
                ],
            )
        };
        let blocks: Vec<(Box<dyn Component>, Vec<Source>)> = vec![
            (
                Box::new(ActuatorComponent::new(
                    actuator.clone(),
                    fluid,
                    air,
                    p.tank_pressure,
                )),
                vec![
                    out(NET, network::CHAMBER_Q),
                    out(NET, network::CHAMBER_Q + 1),
                    Source::External(2),
                ],
            ),
            valve_block(0),
            valve_block(1),
            (
                Box::new(Network::new(circuit.clone(), fluid, air, p.tank_pressure)),
                vec![
                    out(SV[0], valve::Q_A),
                    out(SV[0], valve::Q_B),
                    out(SV[1], valve::Q_A),
                    out(SV[1], valve::Q_B),
                    out(ACT, actuator::OUT_P1),
                    out(ACT, actuator::OUT_P2),
                ],
            ),
        ];
        // chamber pressures, then the port pressures, the valve flows, and the chamber
        // flows those make
        let (pressures, flows) = (
            0..network::CHAMBER_Q,
            network::CHAMBER_Q..network::CHAMBER_Q + 2,
        );
        let system = Composition::new(
            blocks,
            vec![
                (ACT, 0..2),
                (NET, pressures),
                (SV[0], 0..4),
                (SV[1], 0..4),
                (NET, flows),
            ],
        );
        let start = |k: usize| system.block(k).1.start;
        let nodes = start(NET);
        let layout = Layout {
            sv: [start(SV[0]), start(SV[1])],
            nodes,
            passages: nodes + circuit.nodes.len(),
            len: system.n_states(),
        };
        Ok(Bench {
            params: p.clone(),
            valves,
            circuit,
            actuator,
            system,
            layout,
        })
    }

    pub fn params(&self) -> &Params {
        &self.params
    }

    pub fn circuit(&self) -> &Circuit {
        &self.circuit
    }

    pub fn actuator(&self) -> &Actuator {
        &self.actuator
    }

    /// The components and their connections.
    pub fn system(&self) -> &Composition {
        &self.system
    }

    pub fn n_states(&self) -> usize {
        self.layout.len
    }

    /// Mode 1 drives the actuator with SV1 alone: SV2 stays connected, at null.
    fn commands(&self, inputs: &Inputs) -> [f64; 2] {
        match self.params.mode {
            Mode::FourWaySingle => [inputs.u1, 0.0],
            _ => [inputs.u1, inputs.u2],
        }
    }

    /// Rest state at position `y0` with both chambers at half supply pressure plus what
    /// holds the piston's weight, manifold nodes at the pressure of what they join.
    pub fn initial_state(&self, y0: f64, inputs: &Inputs) -> Vec<f64> {
        let p = &self.params;
        let mut x = vec![0.0; self.layout.len];
        let mid = 0.5 * (p.supply_pressure + p.tank_pressure);
        x[Y] = y0;
        let rest = self
            .actuator
            .rest_pressures(p.supply_pressure, p.tank_pressure);
        x[P1..P1 + 2].copy_from_slice(&rest);
        let u = self.commands(inputs);
        for (k, valve) in self.valves.iter().enumerate() {
            let o = self.layout.sv[k];
            valve.initial_state(u[k], &mut x[o..o + valve.n_states()]);
        }
        for k in 0..self.circuit.nodes.len() {
            x[self.layout.nodes + k] = mid;
        }
        // nodes that only see a chamber through passages start at its pressure
        for pass in &self.circuit.passages {
            if let (Port::Node(n), Port::Chamber(c)) = (pass.from, pass.to) {
                x[self.layout.nodes + n] = x[P1 + c];
            }
        }
        x
    }

    /// Absolute tolerances and typical magnitudes of every state, by the components'
    /// one tolerance policy ([`crate::component::tolerances`]).
    pub fn state_scales(&self, rtol: f64) -> (Vec<f64>, Vec<f64>) {
        component::tolerances(self.system.states(), rtol)
    }

    fn external(inputs: &Inputs) -> [f64; 3] {
        [inputs.u1, inputs.u2, inputs.f_ext]
    }

    /// Right-hand side dx/dt = f(x, inputs). Returns the chamber inflows (Q1, Q2) from
    /// the manifold side, which the outputs need too.
    pub fn derivatives(&self, x: &[f64], inputs: &Inputs, dx: &mut [f64]) -> [f64; 2] {
        let s = self.system.derivatives(x, &Self::external(inputs), dx);
        let q = |k: usize| self.system.signal(&s, NET, network::CHAMBER_Q + k);
        [q(0), q(1)]
    }

    /// d(dx_i)/d(x_j) at `x`, row-major n x n, exact: each component's Jacobian chained
    /// through the port connections.
    pub fn jacobian(&self, x: &[f64], inputs: &Inputs, jac: &mut [f64]) {
        self.system.jacobian(x, &Self::external(inputs), jac)
    }

    /// The outputs at state x.
    pub fn outputs(&self, x: &[f64], inputs: &Inputs) -> Outputs {
        let mut dx = vec![0.0; self.layout.len];
        let s = self.system.derivatives(x, &Self::external(inputs), &mut dx);
        let sig = |block: usize, port: usize| self.system.signal(&s, block, port);
        let motion = self
            .actuator
            .motion(x[Y], x[V], [x[P1], x[P1 + 1]], inputs.f_ext);
        Outputs {
            y: x[Y],
            v: x[V],
            a: dx[V],
            p1: x[P1],
            p2: x[P1 + 1],
            p_a1: sig(NET, 0),
            p_b1: sig(NET, 1),
            p_a2: sig(NET, 2),
            p_b2: sig(NET, 3),
            q_a1: sig(SV[0], valve::Q_A),
            q_b1: sig(SV[0], valve::Q_B),
            q_a2: sig(SV[1], valve::Q_A),
            q_b2: sig(SV[1], valve::Q_B),
            q_supply: sig(SV[0], valve::Q_S) + sig(SV[1], valve::Q_S),
            q1: sig(NET, network::CHAMBER_Q),
            q2: sig(NET, network::CHAMBER_Q + 1),
            x_s1: sig(SV[0], valve::X_S),
            x_s2: sig(SV[1], valve::X_S),
            friction: motion.friction,
        }
    }
}

/// Complete simulation state: a plain value, cloned for FMU get/set state.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SimState {
    pub t: f64,
    pub x: Vec<f64>,
    pub inputs: Inputs,
    /// The integrator's next step size, carried across intervals (part of the state so
    /// that a restored run replays bit for bit).
    #[serde(default)]
    pub step: Option<f64>,
    /// The rest of what the integrator carries (its Jacobian, Newton's rate): results
    /// depend on it, so it is state too.
    #[serde(default)]
    pub integrator: Memory,
}

/// A bench with its state: set inputs, advance to a time, read outputs.
#[derive(Debug)]
pub struct Simulation {
    bench: Bench,
    state: SimState,
    tolerances: Tolerances,
    scales: Vec<f64>,
    /// The integrator's buffers and LU: derived from `state.integrator`, never state.
    workspace: Option<Workspace>,
    pub stats: SolverStats,
}

impl Simulation {
    pub fn new(params: &Params) -> Result<Simulation, ParamError> {
        let bench = Bench::new(params)?;
        let inputs = Inputs::default();
        let x = bench.initial_state(params.initial_position, &inputs);
        let (atol, scales) = bench.state_scales(params.solver.rtol);
        let colouring = probe_colouring(&bench, &scales);
        Ok(Simulation {
            tolerances: Tolerances {
                rtol: params.solver.rtol,
                atol,
                fixed_step: params.solver.fixed_step,
            },
            scales,
            state: SimState {
                t: 0.0,
                x,
                inputs,
                step: None,
                integrator: Memory::default(),
            },
            workspace: Some(Workspace::new(colouring).autonomous()),
            bench,
            stats: SolverStats::default(),
        })
    }

    pub fn bench(&self) -> &Bench {
        &self.bench
    }

    pub fn time(&self) -> f64 {
        self.state.t
    }

    pub fn set_inputs(&mut self, inputs: Inputs) {
        self.state.inputs = inputs;
    }

    pub fn inputs(&self) -> Inputs {
        self.state.inputs
    }

    pub fn outputs(&self) -> Outputs {
        self.bench.outputs(&self.state.x, &self.state.inputs)
    }

    /// Integrate with the current inputs up to time `t`. On failure the state is left
    /// where it was, so a caller can retry with a shorter interval.
    pub fn advance_to(&mut self, t: f64) -> Result<(), SolverError> {
        let inputs = self.state.inputs;
        if inputs.u1.is_nan() || inputs.u2.is_nan() || !inputs.f_ext.is_finite() {
            return Err(SolverError::NonFinite { t: self.state.t });
        }
        let mut x = self.state.x.clone();
        let bench = &self.bench;
        let mut step = self.state.step;
        let mut memory = self.state.integrator.clone();
        // the composition's exact Jacobian (component::Composition, checked against
        // differences in model/tests/jacobians.rs) for the Newton matrices
        let jacobian = |_t: f64, x: &[f64], jac: &mut [f64]| bench.jacobian(x, &inputs, jac);
        solver::advance(
            &|_t, x: &[f64], dx: &mut [f64]| {
                bench.derivatives(x, &inputs, dx);
            },
            &mut x,
            self.state.t,
            t,
            &self.tolerances,
            &self.scales,
            &mut self.stats,
            Carry {
                step: &mut step,
                memory: &mut memory,
                workspace: &mut self.workspace,
                jacobian: Some(&jacobian),
            },
        )?;
        self.state.x = x;
        self.state.t = t;
        self.state.step = step;
        self.state.integrator = memory;
        Ok(())
    }

    pub fn state(&self) -> &SimState {
        &self.state
    }

    /// Restore a state taken from a simulation of the same parameters.
    pub fn set_state(&mut self, state: SimState) -> Result<(), String> {
        if state.x.len() != self.bench.n_states() {
            return Err(format!(
                "state has {} values, this bench has {}",
                state.x.len(),
                self.bench.n_states()
            ));
        }
        if !state.t.is_finite() || state.x.iter().any(|v| !v.is_finite()) {
            return Err("state holds non-finite values".into());
        }
        // a restored state (an FMU state from bytes) must be one the bench can be in:
        // absolute pressures are positive, a carried step size is a step size
        let l = self.bench.layout;
        let pressures = state.x[P1..P1 + 2]
            .iter()
            .chain(&state.x[l.nodes..l.passages]);
        if let Some(p) = pressures.into_iter().find(|p| **p <= 0.0) {
            return Err(format!(
                "state holds a non-positive absolute pressure {p} Pa"
            ));
        }
        if state.step.is_some_and(|h| !(h.is_finite() && h > 0.0)) {
            return Err(format!("state holds an invalid step size {:?}", state.step));
        }
        state.integrator.validate(state.x.len())?;
        self.state = state;
        Ok(())
    }
}

/// Probes of the bench's sparsity pattern, at rest states under random commands and
/// forces with every state moved by up to half its scale: enough to see each coupling
/// on either side of the valves' null and of the pressure drops' signs. A fixed seed
/// keeps the colouring, hence the results, the same from run to run.
const PATTERN_PROBES: usize = 8;

/// The colouring of the bench's finite-difference Jacobian (see `solver::jacobian`).
pub fn probe_colouring(bench: &Bench, scales: &[f64]) -> Colouring {
    use rand::{Rng, SeedableRng};
    let n = bench.n_states();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(13);
    let mut pattern = Pattern::diagonal(n);
    let p = &bench.params;
    for _ in 0..PATTERN_PROBES {
        let inputs = Inputs {
            u1: rng.random_range(-10.0..10.0),
            u2: rng.random_range(-10.0..10.0),
            f_ext: rng.random_range(-1e3..1e3),
        };
        let mut x = bench.initial_state(p.initial_position, &inputs);
        for (xi, s) in x.iter_mut().zip(scales) {
            *xi += 0.5 * s * rng.random_range(-1.0..1.0);
        }
        pattern.probe(
            &|_t, x: &[f64], dx: &mut [f64]| {
                bench.derivatives(x, &inputs, dx);
            },
            &x,
            scales,
        );
    }
    Colouring::greedy(&pattern)
}
