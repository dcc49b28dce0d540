//! A servovalve as a component: a restriction, command and the four port pressures in,
//! the port flows, the supply flow and the spool position out.

use std::sync::Arc;

use super::{Component, Jacobian, Port, Signature, State};
use crate::servovalve::{PortPressures, Servovalve};

/// Input ports of a valve (U, P_S, P_T, P_A, P_B), then its outputs (Q_A, Q_B, Q_S, X_S).
pub use crate::servovalve::port::*;

/// A servovalve model behind the component interface.
#[derive(Debug)]
pub struct Valve {
    model: Arc<dyn Servovalve>,
    signature: Signature,
}

impl Valve {
    /// The valve `model`, its ports and states named with `suffix` ("1", "2" or "").
    pub fn new(model: Arc<dyn Servovalve>, suffix: &str) -> Valve {
        let n = model.n_states();
        let mut atol = vec![0.0; n];
        model.absolute_tolerances(&mut atol);
        let states = model
            .state_names()
            .iter()
            .zip(model.state_units())
            .zip(atol)
            // spool states: 1e4 times the tolerance is their working range
            .map(|((name, unit), a)| State::new(format!("{name}{suffix}"), unit, a, a * 1e4))
            .collect();
        let port = |n: &str, unit| Port::new(format!("{n}{suffix}"), unit);
        Valve {
            model,
            signature: Signature {
                states,
                inputs: vec![
                    port("u", "V"),
                    port("P_P", "Pa"),
                    port("P_T", "Pa"),
                    port("P_A", "Pa"),
                    port("P_B", "Pa"),
                ],
                outputs: vec![
                    port("Q_A", "m3/s"),
                    port("Q_B", "m3/s"),
                    port("Q_P", "m3/s"),
                    port("x_s", "m"),
                ],
            },
        }
    }

    pub fn model(&self) -> &dyn Servovalve {
        self.model.as_ref()
    }
}

/// The port pressures among a valve's inputs.
pub fn port_pressures(u: &[f64]) -> PortPressures {
    PortPressures {
        supply: u[P_S],
        tank: u[P_T],
        a: u[P_A],
        b: u[P_B],
    }
}

impl Component for Valve {
    fn signature(&self) -> &Signature {
        &self.signature
    }
    fn derivatives(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
        self.model.derivatives_at(u[U], x, &port_pressures(u), dx)
    }
    fn outputs_at(&self, x: &[f64], u: &[f64], y: &mut [f64]) {
        let q = self.model.flows(u[U], x, &port_pressures(u));
        y[Q_A] = q.a;
        y[Q_B] = q.b;
        y[Q_S] = q.supply;
        y[X_S] = self.model.spool_position(u[U], x);
    }
    fn jacobian(&self, x: &[f64], u: &[f64], jac: &mut Jacobian) {
        self.model.jacobian(u[U], x, &port_pressures(u), jac)
    }
}
