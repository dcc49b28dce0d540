//! Parameters of one servovalve and the identified defaults of the reduced model
//! ([`crate::servovalve::reduced`]): they sit here, below the valve models, because the
//! parameter tree's defaults are built from them and the models are built from the tree.

use super::{BAR, LPM};
use serde::{Deserialize, Serialize};

/// Total leakage of the four lands at null per unit supply-to-tank pressure (m3/s/Pa).
/// The leakage curve of Fig. 2.10(a) peaks at null between 1.5 and 2 L/min (its axis tops
/// at 2 L/min) with 213 bar across the valve; 1.7 L/min is taken. It is also the valve's
/// flow-pressure coefficient at null, the main damping of the loop around null.
pub const NULL_LEAKAGE: f64 = 1.7e-3 / 60.0 / (213.0 * BAR);

/// Spool travel (fraction of rated) over which the null leakage passes from one land to
/// the other. With ports blocked it sets the pressure gain, d(PA-PB)/dx = (Ps-PT)/width;
/// 0.0258 gives the 827 bar/V of Fig. 2.10(b) (213 bar over 0.258 V of spool position).
pub const NULL_WIDTH: f64 = 0.0258;

/// Second-order spool dynamics of the reduced valve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpoolDynamics {
    pub natural_frequency: f64,
    pub damping: f64,
    pub max_spool_rate: f64,
}

/// Values found by a grid search (examples/tune_valve.rs) and checked by
/// `servovalve::reduced::tests::bandwidths_match_the_manufacturer`, so that the -3 dB
/// frequencies with ports blocked are 310 Hz at 40 % and 160 Hz at 90 % input: the linear
/// part sets the small-signal bandwidth, the rate limit (the pilot stage's flow
/// saturation) brings it down at large amplitude.
pub const TUNED_DYNAMICS: SpoolDynamics = SpoolDynamics {
    natural_frequency: 2.0 * std::f64::consts::PI * 440.0,
    damping: 0.6,
    max_spool_rate: 520.0,
};

/// Which servovalve model a valve uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ValveModel {
    /// Static flow law (II.2), optionally with second-order spool dynamics.
    #[default]
    Reduced,
    /// Physical two-stage model of chapter 2 (torque motor, pilot stage, spool, lands).
    TwoStage,
}

/// One MOOG D765 servovalve (reduced model).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ValveParams {
    pub model: ValveModel,
    pub rated_flow: f64,
    pub rated_pressure_drop: f64,
    pub rated_command: f64,
    pub null_bias: f64,
    pub null_leakage: f64,
    pub null_width: f64,
    pub natural_frequency: f64,
    pub damping: f64,
    pub max_spool_rate: f64,
}

impl Default for ValveParams {
    fn default() -> Self {
        let s = TUNED_DYNAMICS;
        ValveParams {
            model: ValveModel::Reduced,
            rated_flow: 19.0 * LPM,          // Table 1.1
            rated_pressure_drop: 70.0 * BAR, // Table 1.1, total drop over both lands
            rated_command: 10.0,             // Table 1.1
            null_bias: 0.0,
            null_leakage: NULL_LEAKAGE,
            null_width: NULL_WIDTH,
            natural_frequency: s.natural_frequency,
            damping: s.damping,
            max_spool_rate: s.max_spool_rate,
        }
    }
}
