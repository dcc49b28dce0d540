//! The component abstraction (ARCHITECTURE.md, "Components"): each physical component of
//! the bench declares once its states (name, unit, tolerance, scale), its input and
//! output ports (named by physics, following the port-causality rule), its derivatives,
//! its outputs and their exact Jacobians. The bench is a [`Composition`] of them; the
//! component FMUs integrate one of them with the same tolerance policy.
//!
//! Jacobians are analytic. At the non-smooth points of the right-hand side (the sign of
//! a pressure drop, a saturation, an end stop) they take the derivative of the branch
//! the right-hand side evaluates, so a Newton iteration sees the model it integrates.

pub mod actuator;
pub mod compose;
pub mod cosim;
pub mod network;
pub mod valve;

pub use crate::fluid::{oil_stiffness_slope, signed_sqrt_slope};
pub use crate::jacobian::Jacobian;
pub use compose::{Composition, Source};

/// A state of a component.
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    pub name: String,
    pub unit: &'static str,
    /// Absolute tolerance at the reference relative tolerance [`REFERENCE_RTOL`].
    pub atol: f64,
    /// Typical magnitude, for sizing differences and norms.
    pub scale: f64,
}

impl State {
    pub fn new(name: impl Into<String>, unit: &'static str, atol: f64, scale: f64) -> State {
        State {
            name: name.into(),
            unit,
            atol,
            scale,
        }
    }
}

/// An input or output port of a component.
#[derive(Debug, Clone, PartialEq)]
pub struct Port {
    pub name: String,
    pub unit: &'static str,
}

impl Port {
    pub fn new(name: impl Into<String>, unit: &'static str) -> Port {
        Port {
            name: name.into(),
            unit,
        }
    }
}

/// The relative tolerance at which the states' absolute tolerances are declared.
pub const REFERENCE_RTOL: f64 = 1e-6;

/// The one tolerance policy of every integration of components: the declared absolute
/// tolerances hold at rtol 1e-6 and tighten in proportion below it (a tighter rtol asks
/// for more digits of small states too); scales are as declared.
pub fn tolerances(states: &[State], rtol: f64) -> (Vec<f64>, Vec<f64>) {
    let f = (rtol / REFERENCE_RTOL).min(1.0);
    (
        states.iter().map(|s| s.atol * f).collect(),
        states.iter().map(|s| s.scale).collect(),
    )
}

/// What a component declares once: its states and its ports, in the order of the slices
/// its methods take.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Signature {
    pub states: Vec<State>,
    pub inputs: Vec<Port>,
    pub outputs: Vec<Port>,
}

/// A physical component: states, ports, derivatives, outputs, exact Jacobian.
pub trait Component: std::fmt::Debug + Send + Sync {
    fn signature(&self) -> &Signature;
    fn states(&self) -> &[State] {
        &self.signature().states
    }
    fn inputs(&self) -> &[Port] {
        &self.signature().inputs
    }
    fn outputs(&self) -> &[Port] {
        &self.signature().outputs
    }
    /// dx/dt at state `x` with inputs `u`.
    fn derivatives(&self, x: &[f64], u: &[f64], dx: &mut [f64]);
    /// [`Component::derivatives`] and [`Component::outputs_of`] at once, for components
    /// whose outputs and derivatives share work.
    fn derivatives_and_outputs(
        &self,
        x: &[f64],
        u: &[f64],
        which: std::ops::Range<usize>,
        dx: &mut [f64],
        y: &mut [f64],
    ) {
        self.outputs_of(x, u, which, y);
        self.derivatives(x, u, dx);
    }
    /// The outputs at state `x` with inputs `u`. An output that does not depend on an
    /// input (its `yu` entries are zero) must not change with it: the composition
    /// evaluates such outputs before that input is known.
    fn outputs_at(&self, x: &[f64], u: &[f64], y: &mut [f64]);
    /// The outputs `which` into `y[which]` (the others may be written too): a composition
    /// evaluating a block twice asks each time for what it needs.
    fn outputs_of(&self, x: &[f64], u: &[f64], which: std::ops::Range<usize>, y: &mut [f64]) {
        let _ = which;
        self.outputs_at(x, u, y)
    }
    /// Exact derivatives of `derivatives` and `outputs_at`, into a cleared `jac`.
    fn jacobian(&self, x: &[f64], u: &[f64], jac: &mut Jacobian);
}
