//! A model run under an experiment's drive, sampled as the acquisition samples the bench:
//! at each sample the commands are decided from what the sensors read (delayed when the
//! `sensor_delay` effect is on) and held until the next sample.

use std::collections::BTreeMap;

use hbmodel::control::{run_loop, Measurement, Timing, COMMAND_LIMIT};
use hbmodel::{Params, Simulation};

use super::analysis::sensor_range;
use super::data::{Drive, Experiment, Measured};

mod recent;

/// Simulated samples, aligned with the measured time base.
#[derive(Debug, Clone, PartialEq)]
pub struct Traces {
    pub time: Vec<f64>,
    /// y, P1, P2 as sampled, u1, u2 as applied.
    pub signals: BTreeMap<&'static str, Vec<f64>>,
}

impl Traces {
    pub fn get(&self, name: &str) -> Option<&[f64]> {
        self.signals.get(name).map(Vec::as_slice)
    }
}

/// Time the bench is held at the record's first command before the record starts (s).
/// A record begins with the bench at rest, but the model starts from mid-supply chamber
/// pressures: with the section 4.4 valve leakage both pressures then creep for tens of
/// milliseconds towards their null level (106.3 -> 103.3 bar over the first 50 ms of the
/// steps, a time constant near 20 ms, measured), a transient no bench shows. The peer
/// bench starts at rest, and this creep alone cost 12 noise levels of its steps record.
/// 0.15 s is seven such time constants (under 0.01 bar left).
pub const SETTLE: f64 = 0.15;

/// Run `params` (with the experiment's operating point) for `n` samples of `period`,
/// asking `command(k, sensed)` for the commands at each sample; returns what was sensed
/// and applied at each sample. Before sample 0 the bench settles for SETTLE under
/// `hold(sensed)`, the first sample's command law (nothing is recorded then).
pub fn run(
    params: &Params,
    experiment: &Experiment,
    n: usize,
    period: f64,
    hold: &dyn Fn(&Measurement) -> [f64; 2],
    command: &mut dyn FnMut(usize, &Measurement) -> [f64; 2],
) -> Result<Sampled, String> {
    Ok(run_finely(params, experiment, n, period, 1, hold, command)?.0)
}

/// What was sensed and applied at each sample.
pub type Sampled = Vec<(Measurement, [f64; 2])>;

/// What the sensors face between the samples: (time from sample 0, outputs).
pub type Fine = Vec<(f64, Measurement)>;

/// `run`, with the bench's outputs besides recorded `substeps` times in each period
/// (time from the record's first sample, what the sensors face; the next sample's
/// instant ends each period): what a sensor with its own dynamics integrates between the samples.
pub fn run_finely(
    params: &Params,
    experiment: &Experiment,
    n: usize,
    period: f64,
    substeps: usize,
    hold: &dyn Fn(&Measurement) -> [f64; 2],
    command: &mut dyn FnMut(usize, &Measurement) -> [f64; 2],
) -> Result<(Sampled, Fine), String> {
    let mut p = params.clone();
    experiment.apply(&mut p);
    let mut sim = Simulation::new(&p).map_err(|e| e.to_string())?;
    let timing = Timing {
        period,
        substeps: 1,
        computation_delay: 0.0,
    };
    let fine = Timing {
        substeps: substeps.max(1),
        ..timing
    };
    let limit = |u: [f64; 2]| u.map(|u| u.clamp(-COMMAND_LIMIT, COMMAND_LIMIT));
    let settle = (SETTLE / period).round() * period;
    let mut rest = |_t: f64, sensed: &Measurement, _exact: &hbmodel::Outputs| limit(hold(sensed));
    run_loop(&mut sim, &mut rest, &|_| 0.0, settle, &timing)
        .map_err(|e| format!("simulation failed while settling: {e}"))?;
    let t0 = sim.time();
    let mut out = Vec::with_capacity(n);
    let mut decide = |t: f64, sensed: &Measurement, _exact: &hbmodel::Outputs| {
        let k = ((t - t0) / period).round() as usize;
        let u = limit(command(k, sensed));
        out.push((*sensed, u));
        u
    };
    let trace = run_loop(
        &mut sim,
        &mut decide,
        &|_| 0.0,
        t0 + n as f64 * period,
        &fine,
    )
    .map_err(|e| format!("simulation failed: {e}"))?;
    let trace = trace
        .iter()
        .map(|s| (s.t - t0, Measurement::of(&s.out)))
        .collect();
    Ok((out, trace))
}

/// The model under the measured experiment's drive, from the last simulations when it
/// was run there a moment ago (`recent`).
pub fn simulate(params: &Params, e: &Experiment, m: &Measured) -> Result<Traces, String> {
    recent::simulated(params, e, m, || integrate(params, e, m)).0
}

/// CPU seconds one integration of the model under the record costs on one core, read
/// from when it ran (a kept simulation is answered at once, `recent`); None if the model
/// cannot be simulated there.
pub fn simulation_cost(params: &Params, e: &Experiment, m: &Measured) -> Option<f64> {
    let (out, cost) = recent::simulated(params, e, m, || integrate(params, e, m));
    out.ok().map(|_| cost)
}

fn integrate(params: &Params, e: &Experiment, m: &Measured) -> Result<Traces, String> {
    let n = m.time.len();
    let period = m.period();
    let samples = match &e.drive {
        Drive::Proportional { kp, reference } => {
            let r = m.get(reference).ok_or("no reference column")?;
            let r0 = r.first().copied().unwrap_or(0.0);
            let hold = |s: &Measurement| {
                let u = kp * (r0 - s.y);
                [u, -u]
            };
            run(params, e, n, period, &hold, &mut |k, s| {
                let u = kp * (r[k.min(n - 1)] - s.y);
                [u, -u]
            })?
        }
        Drive::OpenLoop => {
            let (u1, u2) = (m.get("u1").ok_or("no u1")?, m.get("u2").ok_or("no u2")?);
            let first = [
                u1.first().copied().unwrap_or(0.0),
                u2.first().copied().unwrap_or(0.0),
            ];
            run(params, e, n, period, &|_| first, &mut |k, _| {
                let k = k.min(n - 1);
                [u1[k], u2[k]]
            })?
        }
    };
    let command = |i: usize| samples.iter().map(|s| s.1[i]).collect();
    // read as the acquisition would: a value beyond a sensor's span saturates
    let sensed = |name: &str, f: &dyn Fn(&Measurement) -> f64| -> Vec<f64> {
        let [lo, hi] = sensor_range(name);
        samples.iter().map(|s| f(&s.0).clamp(lo, hi)).collect()
    };
    let signals = BTreeMap::from([
        ("y", sensed("y", &|m| m.y)),
        ("P1", sensed("P1", &|m| m.p1)),
        ("P2", sensed("P2", &|m| m.p2)),
        ("u1", command(0)),
        ("u2", command(1)),
    ]);
    Ok(Traces {
        time: m.time.clone(),
        signals,
    })
}

#[cfg(test)]
mod tests {
    use super::super::hide::{measure, Kind};
    use hbmodel::effects::Effect;
    use hbmodel::sensors::SensorParams;
    use hbmodel::solver::{set_adaptive_method, Method};
    use hbmodel::Params;

    /// Our integrator against diffsol's BDF (a judge we did not write) on the record that
    /// caught it out: the closed-loop sweep of a bench with lossy manifold passages. With
    /// Newton stopped at 0.2 of the tolerance ours left the loop near 2.28 s on another
    /// branch, 271 position and 1500 pressure noise levels away; at 0.01 it stays within
    /// 0.15 and 1.2 (diffsol's ESDIRK34 and BDF differ by 0.15 and 0.85). Same seed, so
    /// the noise cancels in the difference.
    #[test]
    fn the_sweep_with_lossy_passages_matches_diffsol() {
        let mut truth = Params::default();
        for e in [
            Effect::ViscousFriction,
            Effect::ManifoldVolume,
            Effect::ManifoldInertia,
            Effect::ManifoldLosses,
        ] {
            truth.effects.set(e, true);
        }
        truth.manifold.loss_scale = 3.44;
        let run = |m: Method| {
            set_adaptive_method(m);
            let (_, measured) = measure(&truth, Kind::Sweep, 1).unwrap();
            measured
        };
        let (judge, ours) = (run(Method::Bdf), run(Method::FilteredEsdirk34));
        let noise = SensorParams::default();
        for (signal, sigma) in [
            ("y", noise.position_noise),
            ("P1", noise.pressure_noise),
            ("P2", noise.pressure_noise),
        ] {
            let (a, b) = (judge.get(signal).unwrap(), ours.get(signal).unwrap());
            let worst = a
                .iter()
                .zip(b)
                .map(|(a, b)| (a - b).abs() / sigma)
                .fold(0.0, f64::max);
            assert!(worst < 3.0, "{signal}: {worst:.2} noise levels from BDF");
        }
    }
}
