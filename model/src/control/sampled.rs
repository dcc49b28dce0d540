//! A law as it runs on the bench's board: sampled, fed by the DAO2 differentiator or by
//! the exact states, delayed by its computation, saturated at the valves' rated input.

use super::config::AnyLaw;
use super::dao2::Dao2;
use super::law::{Estimate, Law, Reference};
use super::{Measurement, COMMAND_LIMIT};
use crate::bench::Outputs;

/// DAO2 gains of the thesis (section 5.4): Kd0 = 200 1/s, Kd1 = 80 1/s.
pub const DAO2_GAINS: [f64; 2] = [200.0, 80.0];

/// Where the law's velocity and acceleration come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StateSource {
    /// The adaptive differentiator DAO2 on the sampled position (as on the bench).
    Dao2,
    /// The simulation's exact states (a study of the law without estimation error).
    Exact,
}

#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SampledController {
    law: AnyLaw,
    source: StateSource,
    dao2: Dao2,
    period: f64,
    started: bool,
}

impl SampledController {
    pub fn new(law: AnyLaw, source: StateSource, dao2_gains: [f64; 2], period: f64) -> Self {
        SampledController {
            law,
            source,
            dao2: Dao2::new(dao2_gains[0], dao2_gains[1], period),
            period,
            started: false,
        }
    }

    /// Commands at a sample, saturated at +-10 V.
    pub fn sample(
        &mut self,
        t: f64,
        reference: &Reference,
        sensed: &Measurement,
        exact: &Outputs,
    ) -> [f64; 2] {
        if !self.started {
            self.dao2.reset(sensed.y);
            self.law.reset();
            self.started = true;
        }
        let estimated = self.dao2.update(sensed.y);
        let x = match self.source {
            // the law uses the sample itself; DAO2 gives only what is not measured
            StateSource::Dao2 => Estimate {
                y: sensed.y,
                v: estimated[1],
                a: estimated[2],
                p1: sensed.p1,
                p2: sensed.p2,
            },
            StateSource::Exact => Estimate {
                y: exact.y,
                v: exact.v,
                a: exact.a,
                p1: exact.p1,
                p2: exact.p2,
            },
        };
        let u = self.law.commands(t, reference, &x, self.period);
        u.map(|v| v.clamp(-COMMAND_LIMIT, COMMAND_LIMIT))
    }
}
