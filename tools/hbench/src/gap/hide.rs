//! `hbench hide`: measured-like data with a known missing effect. The bench model with
//! the effect switched on at a random, physically plausible magnitude is driven through
//! one of four experiments and sampled as the bench's DS1104 does (1 kHz, sensor noise,
//! 16-bit quantisation); the truth goes into a separate file the workflow never reads.

use std::f64::consts::PI;
use std::path::Path;

use hbmodel::control::scenario::{Signal, KP_SECTION_4_4, SINE_AMPLITUDE};
use hbmodel::control::trajectory::Trajectory;
use hbmodel::control::COMMAND_LIMIT;
use hbmodel::effects::Effect;
use hbmodel::sensors::{Channel, Sensor, SensorParams};
use hbmodel::{Mode, Params};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use serde_json::json;

use super::data::{Drive, Experiment, Measured};
use super::drive::run;
use super::effects::{candidate, Candidate};

/// The experiment types of issue 6.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Closed-loop sine sweep 1-300 Hz, 3.4 mm, proportional control (Figs. 4.9-4.14).
    Sweep,
    /// +-10 mm steps under proportional control (Fig. 4.8).
    Steps,
    /// 7th-order moves -10 -> +10 -> -10 mm under proportional control (section 5.5).
    Moves,
    /// Open-loop chirp of the commands around mid stroke.
    Chirp,
}

impl Kind {
    pub const ALL: [Kind; 4] = [Kind::Sweep, Kind::Steps, Kind::Moves, Kind::Chirp];

    pub fn name(self) -> &'static str {
        match self {
            Kind::Sweep => "sweep",
            Kind::Steps => "steps",
            Kind::Moves => "moves",
            Kind::Chirp => "chirp",
        }
    }

    pub fn parse(s: &str) -> Result<Kind, String> {
        Kind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| format!("unknown experiment '{s}'; known: sweep, steps, moves, chirp"))
    }
}

/// Sweep: log chirp from 1 to 300 Hz over this time (s). 2.5 s gives about 4 cycles below
/// 3 Hz, where the loop is quasi-static, and keeps the run short enough for the fits.
const SWEEP_DURATION: f64 = 2.5;
const SWEEP_BAND: [f64; 2] = [1.0, 300.0];
/// Open-loop chirp: 0.3 V on each valve (3 % of rated), 2-200 Hz over 2 s. At 2 Hz that
/// moves the piston about +-1.5 mm: around mid stroke, far from the stops.
const CHIRP_COMMAND: f64 = 0.3;
const CHIRP_BAND: [f64; 2] = [2.0, 200.0];
const CHIRP_DURATION: f64 = 2.0;
/// Steps and moves: 1 s, one rise and one fall.
const STEPS_DURATION: f64 = 0.65;
const MOVES_DURATION: f64 = 1.0;
/// The DS1104's 1 kHz sampling (line 5711).
const PERIOD: f64 = 1e-3;

/// Phase of a logarithmic chirp from f0 to f1 over `duration`.
fn log_chirp_phase(t: f64, [f0, f1]: [f64; 2], duration: f64) -> f64 {
    let k = (f1 / f0).ln() / duration;
    2.0 * PI * f0 * ((k * t).exp() - 1.0) / k
}

/// The experiment's reference (closed loop) or commands (open loop) at t.
fn signal(kind: Kind) -> (Experiment, f64, Box<dyn Fn(f64) -> f64>) {
    let closed = |y0: f64| Experiment {
        mode: Mode::ThreeWay.number(),
        supply_pressure: 210e5,
        tank_pressure: 2e5,
        initial_position: y0,
        drive: Drive::Proportional {
            kp: KP_SECTION_4_4,
            reference: "y_ref".into(),
        },
    };
    match kind {
        Kind::Sweep => (
            closed(0.0),
            SWEEP_DURATION,
            Box::new(|t| SINE_AMPLITUDE * log_chirp_phase(t, SWEEP_BAND, SWEEP_DURATION).sin()),
        ),
        Kind::Steps => {
            let s = Signal::Steps {
                low: -10e-3,
                high: 10e-3,
                times: vec![0.05, 0.35],
            };
            (
                closed(-10e-3),
                STEPS_DURATION,
                Box::new(move |t| s.at(t)[0]),
            )
        }
        Kind::Moves => {
            let tr = Trajectory::new(&[(0.1, -10e-3, 10e-3, 0.2), (0.6, 10e-3, -10e-3, 0.2)])
                .expect("consistent moves");
            (
                closed(-10e-3),
                MOVES_DURATION,
                Box::new(move |t| tr.at(t)[0]),
            )
        }
        Kind::Chirp => (
            Experiment {
                drive: Drive::OpenLoop,
                ..closed(0.0)
            },
            CHIRP_DURATION,
            Box::new(|t| CHIRP_COMMAND * log_chirp_phase(t, CHIRP_BAND, CHIRP_DURATION).sin()),
        ),
    }
}

/// A plausible magnitude of each parameter the effect's fit adjusts.
pub fn draw(c: &Candidate, rng: &mut Pcg64) -> Vec<(&'static str, f64)> {
    c.fitted
        .iter()
        .map(|f| {
            let [lo, hi] = f.plausible;
            let u: f64 = rng.random();
            let v = if f.log {
                lo * (hi / lo).powf(u)
            } else {
                lo + (hi - lo) * u
            };
            let sign = if f.either_sign && rng.random::<bool>() {
                -1.0
            } else {
                1.0
            };
            (f.path, sign * v)
        })
        .collect()
}

/// Sampled, noisy, quantised data of `truth` under experiment `kind`.
pub fn measure(truth: &Params, kind: Kind, seed: u64) -> Result<(Experiment, Measured), String> {
    let sp = SensorParams {
        seed,
        ..SensorParams::default()
    };
    measure_with(truth, kind, &sp)
}

/// The same through an acquisition of the given noise and resolution.
pub fn measure_with(
    truth: &Params,
    kind: Kind,
    sp: &SensorParams,
) -> Result<(Experiment, Measured), String> {
    let (experiment, duration, f) = signal(kind);
    let n = (duration / PERIOD).round() as usize;
    let mut y_s = Sensor::new(sp, Channel::Position, 0);
    let mut p1_s = Sensor::new(sp, Channel::Pressure, 1);
    let mut p2_s = Sensor::new(sp, Channel::Pressure, 2);
    let mut u_s = Sensor::new(sp, Channel::Exact, 3);
    let mut rows: Vec<[f64; 6]> = Vec::with_capacity(n);
    let kp = match &experiment.drive {
        Drive::Proportional { kp, .. } => Some(*kp),
        Drive::OpenLoop => None,
    };
    run(truth, &experiment, n, PERIOD, &mut |k, s| {
        let t = k as f64 * PERIOD;
        let (y, p1, p2) = (y_s.measure(s.y), p1_s.measure(s.p1), p2_s.measure(s.p2));
        let r = f(t);
        // The controller acts on the sample before the recording's noise: on the bench the
        // same LVDT feeds both, but noise fed back excites the nearly undamped oil-column
        // resonance of a model without friction and leakage (30 bar RMS in P1 on the sweep,
        // measured), a random disturbance no deterministic model can reproduce.
        let u = match kp {
            Some(kp) => (kp * (r - s.y)).clamp(-COMMAND_LIMIT, COMMAND_LIMIT),
            None => r,
        };
        // recorded through the 16-bit converter, applied exactly: quantisation steps fed
        // to the undamped effect-free model ring its resonance too
        let recorded = u_s.measure(u);
        rows.push([r, y, p1, p2, recorded, -recorded]);
        [u, -u]
    })?;
    let col = |i: usize| rows.iter().map(|r| r[i]).collect::<Vec<_>>();
    let mut columns = std::collections::BTreeMap::from([
        ("y".to_string(), col(1)),
        ("P1".to_string(), col(2)),
        ("P2".to_string(), col(3)),
        ("u1".to_string(), col(4)),
        ("u2".to_string(), col(5)),
    ]);
    if kp.is_some() {
        columns.insert("y_ref".into(), col(0));
    }
    let time = (0..n).map(|k| k as f64 * PERIOD).collect();
    Ok((experiment, Measured { time, columns }))
}

/// The known model plus the hidden effects at drawn magnitudes.
pub fn truth(
    base: &Params,
    hidden: &[Effect],
    rng: &mut Pcg64,
) -> (Params, Vec<(&'static str, f64)>) {
    let mut p = base.clone();
    let mut drawn = Vec::new();
    for &e in hidden {
        p.effects.set(e, true);
        let c = candidate(e).expect("hidden effects are candidates");
        for (path, v) in draw(&c, rng) {
            hbmodel::effects::param(path)
                .expect("registered")
                .set(&mut p, v);
            drawn.push((path, v));
        }
        for &needed in e.spec().requires {
            p.effects.set(needed, true);
        }
    }
    (p, drawn)
}

/// `PATH=VALUE` settings of registry parameters, checked against their bounds.
pub fn parse_setting(s: &str) -> Result<(String, f64), String> {
    let (path, value) = s
        .split_once('=')
        .ok_or(format!("expected PATH=VALUE, not '{s}'"))?;
    let spec = hbmodel::effects::param(path.trim())
        .ok_or(format!("'{path}' is not a registry parameter"))?;
    let v: f64 = value
        .trim()
        .parse()
        .map_err(|_| format!("'{value}' is not a number"))?;
    if !(v >= spec.min && v <= spec.max) {
        return Err(format!(
            "{path} = {v} outside [{}, {}] {}",
            spec.min, spec.max, spec.unit
        ));
    }
    Ok((spec.path.to_string(), v))
}

/// `hbench hide`.
pub fn main(
    effects: &[String],
    kind: Kind,
    seed: u64,
    at: &[(String, f64)],
    base: Option<&Path>,
    out: &Path,
    force: bool,
) -> Result<(), String> {
    let hidden: Vec<Effect> = effects
        .iter()
        .filter(|n| n.as_str() != "none")
        .map(|n| {
            Effect::from_name(n)
                .filter(|e| candidate(*e).is_some())
                .ok_or_else(|| {
                    format!(
                        "'{n}' is not an effect the workflow can hide; known: {}",
                        super::effects::names().join(", ")
                    )
                })
        })
        .collect::<Result<_, _>>()?;
    let mut rng = Pcg64::seed_from_u64(seed);
    let base = match base {
        Some(f) => Params::load(f).map_err(|e| e.to_string())?,
        None => Params::default(),
    };
    let (mut p, mut drawn) = truth(&base, &hidden, &mut rng);
    // magnitudes the user fixes replace the drawn ones
    for (path, v) in at {
        let spec = hbmodel::effects::param(path).expect("checked by parse_setting");
        spec.set(&mut p, *v);
        drawn.retain(|(d, _)| *d != spec.path);
        drawn.push((spec.path, *v));
    }
    let (experiment, measured) = measure(&p, kind, seed)?;
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let files = ["measured.csv", "experiment.toml", "answer.json"];
    if !force {
        if let Some(f) = files.iter().find(|f| out.join(f).exists()) {
            return Err(format!(
                "{} exists; use --force or another --out",
                out.join(f).display()
            ));
        }
    }
    let write = |name: &str, text: String| {
        std::fs::write(out.join(name), text).map_err(|e| format!("cannot write {name}: {e}"))
    };
    write("measured.csv", measured.to_csv())?;
    write("experiment.toml", experiment.to_toml())?;
    let answer = json!({
        "hidden": hidden.iter().map(|e| e.name()).collect::<Vec<_>>(),
        "parameters": drawn.iter().map(|(k, v)| (k.to_string(), json!(v))).collect::<serde_json::Map<_, _>>(),
        "experiment": kind.name(),
        "seed": seed,
        "noise": {"position_m": SensorParams::default().position_noise, "pressure_pa": SensorParams::default().pressure_noise, "adc_bits": SensorParams::default().adc_bits},
    });
    write(
        "answer.json",
        serde_json::to_string_pretty(&answer).map_err(|e| e.to_string())?,
    )?;
    println!(
        "wrote {0}/measured.csv ({1} samples), {0}/experiment.toml and the answer in {0}/answer.json",
        out.display(),
        measured.time.len()
    );
    Ok(())
}
