//! `hbench hide`: measured-like data with a known missing effect. The bench model with
//! the effect switched on at a random, physically plausible magnitude is driven through
//! one of four experiments and sampled as the bench's DS1104 does (1 kHz, sensor noise,
//! 16-bit quantisation); the truth goes into a separate file the workflow never reads.
//! The bench may carry a model-form error (variants.rs) and may be the independent peer
//! simulator (peer.rs) instead of the model.

use std::path::Path;

use hbmodel::control::{Measurement, COMMAND_LIMIT};
use hbmodel::effects::Effect;
use hbmodel::sensors::{Channel, Sensor, SensorParams};
use hbmodel::Params;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use serde_json::json;

use std::collections::BTreeMap;

use super::data::{Drive, Experiment, Measured};
use super::drive::run_finely;
use super::effects::{candidate, Candidate};
use super::peer;
use super::variants::{describe, peer_variant, section_4_4, FormError, Simulator};

pub use super::experiments::Kind;
use super::experiments::{Design, PERIOD};
use super::sensor_lag::{lagged, SampledLag, FINE_STEPS};

/// A plausible magnitude of each parameter the effect's fit adjusts and `hide` draws
/// (`Fitted::drawn`). One not drawn takes no number from `rng`, so every case's draws
/// are what they were before it was fitted.
pub fn draw(c: &Candidate, rng: &mut Pcg64) -> Vec<(&'static str, f64)> {
    c.fitted
        .iter()
        .filter(|f| f.drawn)
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

/// The bench a record is taken on: the Rust model with the truth's parameters, or the
/// peer simulator with its variant, and the sensors' lags of the form error.
#[derive(Debug, Clone)]
pub struct Truth {
    pub params: Params,
    pub form: FormError,
    /// The peer's parameters when the peer plays the bench.
    pub peer: Option<serde_json::Map<String, serde_json::Value>>,
}

impl Truth {
    /// The Rust model with these parameters, nothing else.
    pub fn rust(params: Params) -> Self {
        Truth {
            params,
            form: FormError::none(),
            peer: None,
        }
    }

    /// The bench `sim` with the known model's structure, its form error, and the hidden
    /// effects at the drawn magnitudes.
    pub fn new(
        sim: Simulator,
        known: &Params,
        hidden: &[Effect],
        drawn: &[(&'static str, f64)],
        form: &FormError,
    ) -> Self {
        let mut base = known.clone();
        form.apply(&mut base);
        Truth {
            params: with_hidden(&base, hidden, drawn),
            form: form.clone(),
            peer: (sim == Simulator::Peer).then(|| peer_variant(known, hidden, drawn, form)),
        }
    }
}

/// Sampled, noisy, quantised data of the Rust model `truth` under experiment `kind`.
#[cfg(test)]
pub fn measure(truth: &Params, kind: Kind, seed: u64) -> Result<(Experiment, Measured), String> {
    measure_under(truth, &Design::standard(kind), seed)
}

/// The same under any `design`.
#[cfg(test)]
pub fn measure_under(
    truth: &Params,
    design: &Design,
    seed: u64,
) -> Result<(Experiment, Measured), String> {
    let sp = SensorParams {
        seed,
        ..SensorParams::default()
    };
    measure_design(&Truth::rust(truth.clone()), design, &sp)
}

/// Noise-free samples of the bench under the experiment: per sample [reference or
/// command, y, P1, P2, u1] as the sensors deliver them (after their lags) and as applied.
pub fn raw(truth: &Truth, design: &Design) -> Result<(Experiment, Vec<[f64; 5]>), String> {
    let (experiment, signal) = design.samples()?;
    let n = signal.len();
    if let Some(variant) = &truth.peer {
        return Ok((
            experiment.clone(),
            peer::run(variant, &experiment, &signal, PERIOD)?,
        ));
    }
    let kp = match &experiment.drive {
        Drive::Proportional { kp, .. } => Some(*kp),
        Drive::OpenLoop => None,
    };
    // the LVDT's lag acts in the loop (the loop acts on the lagged LVDT, as on a bench
    // whose LVDT conditioner filters), over the sample period; the pressures' lag acts on
    // nothing the loop reads and is run afterwards on the finely recorded pressures
    let ly = SampledLag::new(truth.form.lvdt_lag, PERIOD);
    let tau_p = truth.form.pressure_lag;
    let mut before: Option<f64> = None;
    let mut rows: Vec<[f64; 5]> = Vec::with_capacity(n);
    // the bench rests at the first sample's command before the record starts (the lags
    // start from the first sample they see)
    let r0 = signal.first().copied().unwrap_or(0.0);
    let hold = |s: &hbmodel::control::Measurement| {
        let u = match kp {
            Some(kp) => kp * (r0 - s.y),
            None => r0,
        };
        [u, -u]
    };
    let substeps = if tau_p > 0.0 { FINE_STEPS } else { 1 };
    let (_, fine) = run_finely(
        &truth.params,
        &experiment,
        n,
        PERIOD,
        substeps,
        &hold,
        &mut |k, s| {
            let y = match (rows.last(), before) {
                (Some(&[_, y, ..]), Some(by)) => ly.step(y, by, s.y),
                _ => s.y,
            };
            before = Some(s.y);
            let r = signal[k];
            // The controller acts on the sample before the recording's noise: on the bench
            // the same LVDT feeds both, but noise fed back excites the nearly undamped
            // oil-column resonance of a model without friction and leakage (30 bar RMS in
            // P1 on the sweep, measured), a random disturbance no deterministic model can
            // reproduce.
            let u = match kp {
                Some(kp) => (kp * (r - y)).clamp(-COMMAND_LIMIT, COMMAND_LIMIT),
                None => r,
            };
            rows.push([r, y, s.p1, s.p2, u]);
            [u, -u]
        },
    )?;
    if tau_p > 0.0 && !rows.is_empty() {
        let p = &truth.params;
        let delay = if p.has(Effect::SensorDelay) {
            p.sensors.delay
        } else {
            0.0
        };
        for (column, pick) in [
            (2, (|m: &Measurement| m.p1) as fn(&Measurement) -> f64),
            (3, |m: &Measurement| m.p2),
        ] {
            let series: Vec<(f64, f64)> = fine.iter().map(|(t, m)| (*t, pick(m))).collect();
            let z = lagged(tau_p, rows[0][column], &series, rows.len(), delay);
            for (row, z) in rows.iter_mut().zip(z) {
                row[column] = z;
            }
        }
    }
    Ok((experiment, rows))
}

/// Sampled, noisy, quantised data of the bench `truth` under experiment `kind` as
/// `hbench hide` records it.
pub fn measure_truth(
    truth: &Truth,
    kind: Kind,
    sp: &SensorParams,
) -> Result<(Experiment, Measured), String> {
    measure_design(truth, &Design::standard(kind), sp)
}

/// Sampled, noisy, quantised data of the bench `truth` under `design`.
pub fn measure_design(
    truth: &Truth,
    design: &Design,
    sp: &SensorParams,
) -> Result<(Experiment, Measured), String> {
    let (experiment, rows) = raw(truth, design)?;
    let mut y_s = Sensor::new(sp, Channel::Position, 0);
    let mut p1_s = Sensor::new(sp, Channel::Pressure, 1);
    let mut p2_s = Sensor::new(sp, Channel::Pressure, 2);
    let mut u_s = Sensor::new(sp, Channel::Exact, 3);
    let mut columns: BTreeMap<String, Vec<f64>> = ["y", "P1", "P2", "u1", "u2"]
        .iter()
        .map(|c| (c.to_string(), Vec::with_capacity(rows.len())))
        .collect();
    let closed = matches!(experiment.drive, Drive::Proportional { .. });
    let mut reference = Vec::with_capacity(rows.len());
    for &[r, y, p1, p2, u] in &rows {
        // recorded through the 16-bit converter, applied exactly: quantisation steps fed
        // to the undamped effect-free model ring its resonance too
        let recorded = u_s.measure(u);
        for (c, x) in [
            ("y", y_s.measure(y)),
            ("P1", p1_s.measure(p1)),
            ("P2", p2_s.measure(p2)),
            ("u1", recorded),
            ("u2", -recorded),
        ] {
            columns.get_mut(c).expect("column").push(x);
        }
        reference.push(r);
    }
    if closed {
        columns.insert("y_ref".into(), reference);
    }
    let time = (0..rows.len()).map(|k| k as f64 * PERIOD).collect();
    Ok((experiment, Measured { time, columns }))
}

/// A plausible magnitude of each parameter of a hidden effect, from its candidate's
/// ranges (the payload's is effects::PAYLOAD_RANGE).
fn draw_hidden(hidden: &[Effect], rng: &mut Pcg64) -> Vec<(&'static str, f64)> {
    hidden
        .iter()
        .filter_map(|&e| candidate(e))
        .flat_map(|c| draw(&c, rng))
        .collect()
}

/// `base` with the hidden effects on at the drawn magnitudes.
pub fn with_hidden(base: &Params, hidden: &[Effect], drawn: &[(&'static str, f64)]) -> Params {
    let mut p = base.clone();
    for &e in hidden {
        p.effects.set(e, true);
        for &needed in e.spec().requires {
            p.effects.set(needed, true);
        }
    }
    for &(path, v) in drawn {
        // SV2, when its own valve, shares SV1's spool lands and dynamics, as in the fits
        super::recalibrate::set_fitted(&mut p, path, v);
    }
    p
}

/// The known model plus the hidden effects at drawn magnitudes.
pub fn truth(
    base: &Params,
    hidden: &[Effect],
    rng: &mut Pcg64,
) -> (Params, Vec<(&'static str, f64)>) {
    let drawn = draw_hidden(hidden, rng);
    (with_hidden(base, hidden, &drawn), drawn)
}

/// Effects `hide` can hide: the candidates (the payload among them).
pub fn hideable(e: Effect) -> bool {
    candidate(e).is_some()
}

/// `NAME=VALUE` for `hide --form-at`; the name is checked against the drawn form error
/// (`FormError::set`), which depends on the simulator.
pub fn parse_form_setting(s: &str) -> Result<(String, f64), String> {
    let (name, value) = s
        .split_once('=')
        .ok_or(format!("expected NAME=VALUE, not '{s}'"))?;
    let v: f64 = value
        .trim()
        .parse()
        .map_err(|_| format!("'{value}' is not a number"))?;
    Ok((name.trim().to_string(), v))
}

/// `PATH=VALUE` settings of registry parameters, checked against their bounds.
pub fn parse_setting(s: &str) -> Result<(String, f64), String> {
    let (path, v) = parse_form_setting(s)?;
    let spec =
        hbmodel::params::param(&path).ok_or(format!("'{path}' is not a registry parameter"))?;
    if !(v >= spec.min && v <= spec.max) {
        return Err(format!(
            "{path} = {v} outside [{}, {}] {}",
            spec.min, spec.max, spec.unit
        ));
    }
    Ok((spec.path.to_string(), v))
}

/// What `hbench hide` is asked for.
pub struct Options<'a> {
    pub effects: &'a [String],
    pub kind: Kind,
    pub seed: u64,
    pub at: &'a [(String, f64)],
    pub base: Option<&'a Path>,
    pub out: &'a Path,
    pub force: bool,
    pub simulator: Simulator,
    /// Draw a model-form error (FormError::draw) on top of the simulator's own.
    pub form_error: bool,
    /// Parts of the drawn form error replaced (`FormError::set`); needs `form_error`.
    pub form_at: &'a [(String, f64)],
}

/// `hbench hide`.
pub fn main(o: &Options) -> Result<(), String> {
    let (kind, seed, out) = (o.kind, o.seed, o.out);
    let hidden: Vec<Effect> = o
        .effects
        .iter()
        .filter(|n| n.as_str() != "none")
        .map(|n| {
            Effect::from_name(n)
                .filter(|e| hideable(*e))
                .ok_or_else(|| {
                    format!(
                        "'{n}' is not an effect the workflow can hide; known: {}, payload",
                        super::effects::names().join(", ")
                    )
                })
        })
        .collect::<Result<_, _>>()?;
    let mut rng = Pcg64::seed_from_u64(seed);
    // with model-form error the known model is section 4.4's, never the truth's structure
    let known = match o.base {
        Some(f) => Params::load(f).map_err(|e| e.to_string())?,
        None if o.form_error || o.simulator == Simulator::Peer => section_4_4(),
        None => Params::default(),
    };
    let mut drawn = draw_hidden(&hidden, &mut rng);
    // magnitudes the user fixes replace the drawn ones
    for (path, v) in o.at {
        let spec = hbmodel::params::param(path).expect("checked by parse_setting");
        drawn.retain(|(d, _)| *d != spec.path);
        drawn.push((spec.path, *v));
    }
    if !o.form_at.is_empty() && !o.form_error {
        return Err("--form-at changes the drawn form error: give --form-error too".into());
    }
    let mut form = if o.form_error {
        FormError::for_seed(o.simulator, seed)
    } else {
        FormError::none()
    };
    for (name, v) in o.form_at {
        form.set(o.simulator, name, *v)?;
    }
    let truth = Truth::new(o.simulator, &known, &hidden, &drawn, &form);
    let sp = SensorParams {
        seed,
        ..SensorParams::default()
    };
    let (experiment, measured) = measure_truth(&truth, kind, &sp)?;
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let files = [
        "measured.csv",
        "experiment.toml",
        "answer.json",
        "known_model.toml",
    ];
    if !o.force {
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
    // the model to give `gap --model`: what is known, not the truth
    write("known_model.toml", known.to_toml())?;
    let answer = json!({
        "bench": describe(o.simulator, &form, truth.peer.as_ref()),
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
        "wrote {0}/measured.csv ({1} samples), {0}/experiment.toml, the known model in {0}/known_model.toml and the answer in {0}/answer.json",
        out.display(),
        measured.time.len()
    );
    Ok(())
}
