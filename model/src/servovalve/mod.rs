//! The servovalve interface shared by every valve model of the bench.
//!
//! A valve is a restriction: it takes the command and the pressures at its four ports
//! and returns the flows at A and B (ARCHITECTURE.md, port causality). Models with internal
//! dynamics own a slice of the bench state vector; static models own none.

pub mod reduced;
pub mod two_stage;

// The orifice law every restriction of the bench uses, declared with the oil.
pub use crate::fluid::signed_sqrt;

/// The port layout of a valve's Jacobian, and of the valve as a component
/// (`crate::component::valve`): inputs, then outputs.
pub mod port {
    pub const U: usize = 0;
    pub const P_S: usize = 1;
    pub const P_T: usize = 2;
    pub const P_A: usize = 3;
    pub const P_B: usize = 4;
    pub const Q_A: usize = 0;
    pub const Q_B: usize = 1;
    pub const Q_S: usize = 2;
    pub const X_S: usize = 3;
}

/// Absolute pressures at the four ports (Pa).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PortPressures {
    pub supply: f64,
    pub tank: f64,
    pub a: f64,
    pub b: f64,
}

/// Flows leaving the valve at ports A and B into their lines (m3/s).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PortFlows {
    pub a: f64,
    pub b: f64,
    /// Flow drawn from the supply port P, pilot stage included (m3/s): the hydraulic
    /// power the valve takes is P_supply * supply.
    pub supply: f64,
}

/// One servovalve model. `command` is the valve input in volts as on the bench (+-10 V).
pub trait Servovalve: std::fmt::Debug + Send + Sync {
    /// Number of states this model owns in the bench state vector.
    fn n_states(&self) -> usize;
    /// Rest state for a constant command.
    fn initial_state(&self, command: f64, x: &mut [f64]);
    /// Absolute tolerances of the owned states (their natural scale times a small factor).
    fn absolute_tolerances(&self, atol: &mut [f64]);
    /// Time derivative of the owned states.
    fn derivatives(&self, command: f64, x: &[f64], dx: &mut [f64]);
    /// Time derivative of the owned states when the port pressures are known, for models
    /// whose dynamics feel them (pilot stage fed from P, flow forces on the spool). The
    /// default ignores them.
    fn derivatives_at(&self, command: f64, x: &[f64], p: &PortPressures, dx: &mut [f64]) {
        let _ = p;
        self.derivatives(command, x, dx)
    }
    /// Spool position (m), positive opening P->A and B->T.
    fn spool_position(&self, command: f64, x: &[f64]) -> f64;
    /// Port flows for the current spool state and port pressures.
    fn flows(&self, command: f64, x: &[f64], p: &PortPressures) -> PortFlows;
    /// Names of the owned states, as the FMUs and the solver's messages show them.
    fn state_names(&self) -> &'static [&'static str];
    /// SI units of the owned states.
    fn state_units(&self) -> &'static [&'static str];
    /// Exact Jacobian of `derivatives_at`, `flows` and `spool_position` in the port
    /// layout of [`crate::component::valve`], into a cleared `jac`.
    fn jacobian(
        &self,
        command: f64,
        x: &[f64],
        p: &PortPressures,
        jac: &mut crate::jacobian::Jacobian,
    );
}

/// The valve model a parameter set asks for, for one valve's parameters `vp`: the
/// effects `valve_dynamics`, `internal_leakage` and `temperature` of `p` apply.
pub fn build(vp: &crate::params::ValveParams, p: &crate::params::Params) -> Box<dyn Servovalve> {
    use crate::effects::Effect;
    // (A.14)-(A.16): laminar conductances scale with 1/mu
    let mu_ratio = p.fluid_in_use().viscosity_ratio();
    match vp.model {
        crate::params::ValveModel::Reduced => Box::new(reduced::ReducedServovalve::new(
            vp,
            p.has(Effect::ValveDynamics),
            p.has(Effect::InternalLeakage),
            1.0 / mu_ratio,
        )),
        // always with its spool dynamics and its land leakage, which is part of the
        // identified flow model (2.26)-(2.31): see two_stage/
        crate::params::ValveModel::TwoStage => Box::new(two_stage::TwoStageServovalve::new(vp, p)),
    }
}
