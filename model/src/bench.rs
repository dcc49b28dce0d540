//! The assembled bench: SV1, SV2, manifold and actuator between supply and tank, in one
//! state vector for one stiff solver.
//!
//! State layout: `[y, v, P1, P2 | SV1 states | SV2 states | node pressures | passage flows]`.

use crate::actuator::{fluid_in_use, oil_stiffness, Actuator};
use crate::effects::Effect;
use crate::fluid::FluidParams;
use crate::manifold::{Circuit, NetworkState, Port};
use crate::params::{Mode, ParamError, Params};
use crate::servovalve::{self, PortFlows, PortPressures, Servovalve};
use crate::solver::{self, SolverError, SolverStats, Tolerances};

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

/// The bench model: parameters turned into the elements the right-hand side needs.
#[derive(Debug)]
pub struct Bench {
    params: Params,
    valves: [Box<dyn Servovalve>; 2],
    circuit: Circuit,
    actuator: Actuator,
    fluid: FluidParams,
    air: bool,
    layout: Layout,
}

impl Bench {
    pub fn new(params: &Params) -> Result<Bench, ParamError> {
        params.validate()?;
        let p = params;
        let fluid = fluid_in_use(p);
        let valves = [
            servovalve::build(&p.sv1, p),
            servovalve::build(p.sv2_effective(), p),
        ];
        let circuit = Circuit::from_params(p);
        let actuator = Actuator::from_params(p, circuit.chamber_volume, circuit.added_mass);
        let n0 = valves[0].n_states();
        let n1 = valves[1].n_states();
        let sv = [4, 4 + n0];
        let nodes = 4 + n0 + n1;
        let passages = nodes + circuit.nodes.len();
        let layout = Layout {
            sv,
            nodes,
            passages,
            len: passages + circuit.passages.len(),
        };
        Ok(Bench {
            params: p.clone(),
            valves,
            circuit,
            actuator,
            air: p.has(Effect::EntrainedAir),
            fluid,
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

    /// Absolute tolerances and typical magnitudes of every state.
    pub fn state_scales(&self, rtol: f64) -> (Vec<f64>, Vec<f64>) {
        let n = self.layout.len;
        let mut atol = vec![0.0; n];
        let mut scale = vec![0.0; n];
        // 1 nm, 1 um/s, 1 Pa, 1e-3 L/min: well below sensor resolution, tightened with rtol
        let f = (rtol / 1e-6).min(1.0);
        atol[Y] = 1e-9 * f;
        atol[V] = 1e-6 * f;
        atol[P1] = 1.0 * f;
        atol[P1 + 1] = 1.0 * f;
        scale[Y] = 1e-3;
        scale[V] = 1e-2;
        scale[P1] = 1e6;
        scale[P1 + 1] = 1e6;
        for (k, valve) in self.valves.iter().enumerate() {
            let o = self.layout.sv[k];
            let m = valve.n_states();
            valve.absolute_tolerances(&mut atol[o..o + m]);
            for i in o..o + m {
                scale[i] = atol[i] * 1e4;
                atol[i] *= f;
            }
        }
        for i in self.layout.nodes..self.layout.passages {
            atol[i] = 1.0 * f;
            scale[i] = 1e6;
        }
        for i in self.layout.passages..n {
            atol[i] = 1e-3 * crate::params::LPM * f;
            scale[i] = 1e-5;
        }
        (atol, scale)
    }

    fn network_state<'a>(&self, x: &'a [f64]) -> NetworkState<'a> {
        let l = &self.layout;
        NetworkState {
            nodes: &x[l.nodes..l.passages],
            flows: &x[l.passages..l.len],
            chambers: [x[P1], x[P1 + 1]],
            tank: self.params.tank_pressure,
        }
    }

    fn pressure(&self, x: &[f64], port: Port) -> f64 {
        self.network_state(x).pressure(port)
    }

    fn bulk_modulus(&self, p: f64) -> f64 {
        oil_stiffness(&self.fluid, self.air, p)
    }

    /// Valve port flows for the state.
    fn valve_flows(&self, x: &[f64], u: [f64; 2]) -> [[f64; 2]; 2] {
        self.valve_port_flows(x, u).map(|f| [f.a, f.b])
    }

    fn valve_port_flows(&self, x: &[f64], u: [f64; 2]) -> [PortFlows; 2] {
        std::array::from_fn(|k| {
            let valve = &self.valves[k];
            let o = self.layout.sv[k];
            valve.flows(
                u[k],
                &x[o..o + valve.n_states()],
                &self.port_pressures(x, k),
            )
        })
    }

    /// Pressures at the four ports of valve k.
    fn port_pressures(&self, x: &[f64], k: usize) -> PortPressures {
        let ports = self.circuit.valve_ports[k];
        PortPressures {
            supply: self.params.supply_pressure,
            tank: self.params.tank_pressure,
            a: self.pressure(x, ports[0]),
            b: self.pressure(x, ports[1]),
        }
    }

    /// Right-hand side dx/dt = f(x, inputs). Returns the chamber inflows (Q1, Q2) from
    /// the manifold side, which the outputs need too.
    pub fn derivatives(&self, x: &[f64], inputs: &Inputs, dx: &mut [f64]) -> [f64; 2] {
        let l = &self.layout;
        let act = &self.actuator;
        let u = self.commands(inputs);
        let p = [x[P1], x[P1 + 1]];
        let qv = self.valve_flows(x, u);
        let (dx_rest, dx_flows) = dx.split_at_mut(l.passages);
        let q_ch = self.circuit.derivatives(
            &self.network_state(x),
            &qv,
            |p| self.bulk_modulus(p),
            &mut dx_rest[l.nodes..],
            dx_flows,
        );
        let dp = act.pressure_derivatives(x[Y], x[V], p, q_ch, self.params.tank_pressure, |p| {
            self.bulk_modulus(p)
        });
        dx[P1..P1 + 2].copy_from_slice(&dp);
        // (4.4) motion
        dx[Y] = x[V];
        dx[V] = act.motion(x[Y], x[V], p, inputs.f_ext).acceleration;
        for (k, valve) in self.valves.iter().enumerate() {
            let o = l.sv[k];
            let m = valve.n_states();
            // the port pressures reach valves whose dynamics feel them (flow forces)
            let pp = self.port_pressures(x, k);
            valve.derivatives_at(u[k], &x[o..o + m], &pp, &mut dx[o..o + m]);
        }
        q_ch
    }

    /// The outputs at state x.
    pub fn outputs(&self, x: &[f64], inputs: &Inputs) -> Outputs {
        let mut dx = vec![0.0; self.layout.len];
        let q_in = self.derivatives(x, inputs, &mut dx);
        let u = self.commands(inputs);
        let qv = self.valve_port_flows(x, u);
        let ports = &self.circuit.valve_ports;
        let motion = self
            .actuator
            .motion(x[Y], x[V], [x[P1], x[P1 + 1]], inputs.f_ext);
        let spool = |k: usize| {
            let o = self.layout.sv[k];
            self.valves[k].spool_position(u[k], &x[o..o + self.valves[k].n_states()])
        };
        Outputs {
            y: x[Y],
            v: x[V],
            a: dx[V],
            p1: x[P1],
            p2: x[P1 + 1],
            p_a1: self.pressure(x, ports[0][0]),
            p_b1: self.pressure(x, ports[0][1]),
            p_a2: self.pressure(x, ports[1][0]),
            p_b2: self.pressure(x, ports[1][1]),
            q_a1: qv[0].a,
            q_b1: qv[0].b,
            q_a2: qv[1].a,
            q_b2: qv[1].b,
            q_supply: qv[0].supply + qv[1].supply,
            q1: q_in[0],
            q2: q_in[1],
            x_s1: spool(0),
            x_s2: spool(1),
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
}

/// A bench with its state: set inputs, advance to a time, read outputs.
#[derive(Debug)]
pub struct Simulation {
    bench: Bench,
    state: SimState,
    tolerances: Tolerances,
    scales: Vec<f64>,
    pub stats: SolverStats,
}

impl Simulation {
    pub fn new(params: &Params) -> Result<Simulation, ParamError> {
        let bench = Bench::new(params)?;
        let inputs = Inputs::default();
        let x = bench.initial_state(params.initial_position, &inputs);
        let (atol, scales) = bench.state_scales(params.solver.rtol);
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
            },
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
        solver::integrate_from(
            |_t, x, dx| {
                bench.derivatives(x, &inputs, dx);
            },
            &mut x,
            self.state.t,
            t,
            &self.tolerances,
            &self.scales,
            &mut self.stats,
            &mut step,
        )?;
        self.state.x = x;
        self.state.t = t;
        self.state.step = step;
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
        self.state = state;
        Ok(())
    }
}
