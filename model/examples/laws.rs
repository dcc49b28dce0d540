//! The thesis's control laws on the full bench (mode 3) following the 7th-order moves:
//! max and standard deviation of the transient error, mean and standard deviation of the
//! static error, in the form of Tables 5.1, 6.1 and 7.1.
use hbmodel::control::config::{ControllerParams, LawKind};
use hbmodel::control::law::Reference;
use hbmodel::control::sampled::StateSource;
use hbmodel::control::trajectory::Trajectory;
use hbmodel::control::{run_sampled, Timing};
use hbmodel::{Effect, Mode, Params, Simulation};

fn main() {
    let payload: f64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.0);
    let traj = Trajectory::thesis();
    let reference = |t: f64| Reference {
        y: traj.at(t),
        p: [80e5, 0.0],
    };
    for (law, kp) in [
        (LawKind::Proportional, 5200.0),
        (LawKind::YLambda, 0.0),
        (LawKind::PY, 0.0),
        (LawKind::ModelFree, 0.0),
        (LawKind::RestrictedModel, 0.0),
    ] {
        let mut p = Params::thesis_bench(Mode::ThreeWay);
        p.initial_position = -0.01;
        if payload > 0.0 {
            p.effects.set(Effect::Payload, true);
            p.actuator.payload_mass = payload;
        }
        let mut cp = ControllerParams {
            law,
            ..ControllerParams::default()
        };
        if kp > 0.0 {
            cp.kp = kp;
        }
        if std::env::var("LOW").is_ok() {
            cp.c = [500.0, 400.0, 400.0, 400.0];
        }
        cp.source = if std::env::var("EXACT").is_ok() {
            StateSource::Exact
        } else {
            StateSource::Dao2
        };
        let mut ctrl = cp.controller(&p);
        let mut sim = Simulation::new(&p).unwrap();
        let t0 = std::time::Instant::now();
        let r = run_sampled(
            &mut sim,
            &mut ctrl,
            &reference,
            2.6,
            &Timing {
                period: 1e-3,
                substeps: 1,
                computation_delay: 0.0,
            },
        );
        match r {
            Ok(trace) => {
                let moving: Vec<f64> = trace
                    .iter()
                    .filter(|s| (s.t > 1.0 && s.t < 1.3) || (s.t > 2.0 && s.t < 2.3))
                    .map(|s| (s.out.y - s.reference) * 1e6)
                    .collect();
                let still: Vec<f64> = trace
                    .iter()
                    .filter(|s| (s.t > 1.6 && s.t < 2.0) || (s.t > 2.4))
                    .map(|s| (s.out.y - s.reference) * 1e6)
                    .collect();
                let max = moving.iter().fold(0.0f64, |a, b| a.max(b.abs()));
                let mean = still.iter().sum::<f64>() / still.len() as f64;
                let std = (still.iter().map(|e| (e - mean).powi(2)).sum::<f64>()
                    / still.len() as f64)
                    .sqrt();
                println!("{law:?}: max transient {max:.0} um, static mean {mean:.1} um std {std:.1} um ({:?})", t0.elapsed());
            }
            Err(e) => println!("{law:?}: failed {e}"),
        }
    }
}
