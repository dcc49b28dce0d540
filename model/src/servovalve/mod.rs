//! The servovalve interface shared by every valve model of the bench.
//!
//! A valve is a restriction: it takes the command and the pressures at its four ports
//! and returns the flows at A and B (DESIGN.md, port causality). Models with internal
//! dynamics own a slice of the bench state vector; static models own none.

pub mod reduced;
pub mod two_stage;

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
}

/// The valve model a parameter set asks for, for one valve's parameters `vp`: the
/// effects `valve_dynamics`, `internal_leakage` and `temperature` of `p` apply.
pub fn build(vp: &crate::params::ValveParams, p: &crate::params::Params) -> Box<dyn Servovalve> {
    use crate::effects::Effect;
    // (A.14)-(A.16): laminar conductances scale with 1/mu
    let mu_ratio = crate::actuator::fluid_in_use(p).viscosity_ratio();
    match vp.model {
        crate::params::ValveModel::Reduced => Box::new(reduced::ReducedServovalve::new(
            vp,
            p.has(Effect::ValveDynamics),
            p.has(Effect::InternalLeakage),
            1.0 / mu_ratio,
        )),
        // always with its spool dynamics and its land leakage, which is part of the
        // identified flow model (2.26)-(2.31): see two_stage.rs
        crate::params::ValveModel::TwoStage => Box::new(two_stage::TwoStageServovalve::new(vp, p)),
    }
}

/// Orifice law with a laminar core: sign(dp)*sqrt(|dp|) away from zero, linear within
/// about `dp_transition` of it, so the flow and its derivative stay finite at dp = 0
/// (a sharp square root would give the stiff solver an infinite Jacobian at null).
pub fn signed_sqrt(dp: f64, dp_transition: f64) -> f64 {
    dp / (dp * dp + dp_transition * dp_transition).sqrt().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signed_sqrt_is_odd_smooth_and_turbulent_far_from_zero() {
        let t = 1e4;
        assert_eq!(signed_sqrt(0.0, t), 0.0);
        assert!((signed_sqrt(-5e6, t) + signed_sqrt(5e6, t)).abs() < 1e-12);
        assert!((signed_sqrt(100e5, t) / (100e5f64).sqrt() - 1.0).abs() < 1e-6);
        // finite slope at zero: 1/sqrt(t)
        let h = 1e-3;
        let slope = (signed_sqrt(h, t) - signed_sqrt(-h, t)) / (2.0 * h);
        assert!((slope * t.sqrt() - 1.0).abs() < 1e-6);
    }
}
