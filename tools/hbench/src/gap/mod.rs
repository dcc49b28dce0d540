//! `hbench gap`: compare the model with measured data, find where they disagree, name the
//! missing physical effect, add it with fitted parameters and show the gap shrink; repeat
//! until the data are explained within their noise or no candidate helps.
//!
//! The gap is the RMS of the differences between measured and simulated samples of y, P1
//! and P2, each in units of its own noise level (estimated from the data): 1 is the noise
//! floor. A candidate effect wins when its fit lowers the chi-square (the sum of squared
//! normalised differences), divided by the residual's correlation time tau, by more than
//! the Bayesian information criterion's price of its parameters, k ln(N / tau), and by
//! more than MIN_IMPROVEMENT of the gap (`evidence`: a coloured residual is worth fewer
//! independent samples than it has).

pub mod advice;
pub mod analysis;
pub mod blind;
pub mod data;
pub mod drive;
pub mod effects;
pub mod evidence;
pub mod experiments;
pub mod fit;
pub mod hide;
pub mod peer;
pub mod recalibrate;
mod report;
pub mod resonance;
pub mod variants;

use std::path::{Path, PathBuf};

use hbmodel::Params;
use serde::Serialize;

use analysis::{localise, noise, quantum, Localisation};
use data::{load_experiment, load_measured, Experiment, Measured, COMPARED};
use drive::{simulate, Traces};
use fit::{fit, Fit, Target};

/// A gap at or below this is reported as the noise floor: the noise estimate itself is
/// uncertain by a few percent. The candidates are still tried there: an effect that is
/// small against the noise can still pay its information-criterion price.
pub const NOISE_FLOOR_GAP: f64 = 1.1;
/// The least relative improvement of the gap for which an effect is worth adding, on top
/// of its information-criterion price: a guard against the residual's samples not being
/// as independent as the criterion assumes.
pub const MIN_IMPROVEMENT: f64 = 0.01;
/// At most this many effects are added in one run.
pub const MAX_STEPS: usize = 4;

/// One accepted step: an effect added, or a recalibration of the known model.
#[derive(Debug, Clone, Serialize)]
pub struct Step {
    pub kind: effects::StepKind,
    /// The registry effect added, or whose parameters were re-fitted (None: the base
    /// model's, such as the bulk modulus).
    pub effect: Option<String>,
    /// What the reports call the step: the effect, or the base parameter re-fitted.
    pub name: String,
    /// Effects `effect` requires that were not yet in the model and came on with it at
    /// their built-in sizes (the manifold losses bring the passages' volume and inertia).
    pub brings: Vec<String>,
    pub parameters: serde_json::Map<String, serde_json::Value>,
    pub gap_before: f64,
    pub gap_after: f64,
    /// Every candidate's fitted gap and score (chi-square drop / tau minus k ln(N / tau)).
    pub candidates: Vec<Scored>,
    /// Independent samples the residual before this step was worth (N / tau).
    pub effective_samples: f64,
    /// How strongly the data prefer this effect over the runner-up.
    pub preference: Option<evidence::Preference>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Scored {
    pub effect: String,
    pub gap: f64,
    pub score: f64,
    pub parameters: serde_json::Map<String, serde_json::Value>,
}

/// The workflow's result.
pub struct Outcome {
    pub steps: Vec<Step>,
    pub initial_gap: f64,
    pub remaining_gap: f64,
    pub noise: Vec<(&'static str, f64)>,
    pub model: Params,
    pub start: Params,
    pub first: Localisation,
    pub last: Localisation,
    pub before: Traces,
    pub after: Traces,
    pub verdict: String,
    /// The last round's candidates, none of which was added: why the workflow stopped.
    pub rejected: Vec<Scored>,
    /// Independent samples the final residual is worth (N / tau).
    pub effective_samples: f64,
    /// Which experiment would tell the leading models apart, when this record cannot.
    pub advice: Option<advice::Advice>,
}

/// Noise of every compared signal the data hold.
pub fn noise_levels(m: &Measured) -> Vec<(&'static str, f64)> {
    COMPARED
        .iter()
        .filter_map(|&s| m.get(s).map(|x| (s, noise(x, quantum(s)))))
        .collect()
}

fn json_values(values: &[(&'static str, f64)]) -> serde_json::Map<String, serde_json::Value> {
    values
        .iter()
        .map(|(k, v)| (k.to_string(), serde_json::json!(v)))
        .collect()
}

/// Fit every candidate in parallel on all cores, with a progress bar when asked.
///
/// An effect that needs others (manifold losses need the passages' volumes and inertia)
/// is tried with them on at their built-in sizes: a bench whose passages lose much can
/// look like neither the lossless passages nor no passages at all (with losses 3.4 times
/// the built-in ones hidden on the sweep, volume alone and inertia alone each fitted
/// worse than nothing and the valve's lag was named, on data from the integrator before
/// its Newton tolerance was tightened; docs/gap.md). Such a candidate is several
/// effects at once, and its simulations carry the passages' fast oil columns (4-7 s of
/// CPU per sweep against 0.2-0.5 s): it is tried only when no candidate of one effect
/// brings the gap to the noise floor.
///
/// The recalibrations open (`recalibrations`) are fitted beside the single effects.
fn fit_all(
    target: &Target,
    model: &Params,
    carried: &[effects::Fitted],
    recalibrations: Vec<effects::Candidate>,
    progress: bool,
) -> Vec<Fit> {
    let (mut single, joint): (Vec<_>, Vec<_>) = effects::all()
        .into_iter()
        .filter(|c| c.effect.is_some_and(|e| !model.has(e)))
        .partition(|c| {
            c.effect
                .is_some_and(|e| e.spec().requires.iter().all(|r| model.has(*r)))
        });
    single.extend(recalibrations);
    let fit_in_parallel = |candidates: &[effects::Candidate]| {
        let bar = crate::parallel::bar(candidates.len(), "fitting", progress);
        // in registry order, as the candidates
        crate::parallel::map(
            candidates,
            &bar,
            |c| c.name(),
            |c| fit(target, model, c, carried),
        )
    };
    let mut fits = fit_in_parallel(&single);
    let floor_reached = fits.iter().any(|f| f.gap <= NOISE_FLOOR_GAP);
    if !floor_reached && !joint.is_empty() {
        fits.extend(fit_in_parallel(&joint));
    }
    fits
}

/// Run the workflow on loaded data, with recalibrations within the default bounds.
pub fn run(
    start: &Params,
    e: &Experiment,
    m: &Measured,
    progress: bool,
) -> Result<Outcome, String> {
    run_with(start, e, m, progress, recalibrate::DEFAULT_FRACTION)
}

/// Run the workflow; the base model's parameters may be re-fitted within +-`within` of
/// their known values (0: no recalibration of them).
pub fn run_with(
    start: &Params,
    e: &Experiment,
    m: &Measured,
    progress: bool,
    within: f64,
) -> Result<Outcome, String> {
    let noise = noise_levels(m);
    if noise.is_empty() {
        return Err("the data hold none of y, P1, P2 to compare with".into());
    }
    let target = Target {
        measured: m,
        experiment: e,
        noise: noise.clone(),
    };
    let n = target.len() as f64;
    let mut model = start.clone();
    let before = simulate(&model, e, m)?;
    let first = localise(m, e, &before, &noise);
    let initial_gap = target.gap(&model);
    let mut gap = initial_gap;
    let mut steps = Vec::new();
    let mut loc = first.clone();
    let mut carried: Vec<effects::Fitted> = Vec::new();
    let (mut rejected, mut final_effective) = (Vec::new(), n);
    // the last round's tau and (score, fit) of each candidate, for the advice
    let mut last_round: (f64, Vec<(f64, Fit)>) = (1.0, Vec::new());
    let verdict = loop {
        if steps.len() == MAX_STEPS {
            break format!("stopped after {MAX_STEPS} effects with the gap at {gap:.2}");
        }
        let done: Vec<&str> = carried.iter().map(|f| f.path).collect();
        let mut open = recalibrate::candidates(&model, within, &done);
        if within <= 0.0 {
            open.retain(|c| c.effect.is_some());
        }
        let fits = fit_all(&target, &model, &carried, open, progress);
        let chi2 = gap * gap * n;
        // what the residual left by the model so far is worth: a missing effect leaves
        // a coloured residual, whose samples are not independent
        let (effective, tau) = target.residuals(&model).map_or((n, 1.0), |r| {
            evidence::effective_samples(r.as_slice(), noise.len())
        });
        let scored: Vec<(Scored, &Fit)> = fits
            .iter()
            .map(|f| {
                let k = f.values.len() as f64;
                let s = Scored {
                    effect: f.name.clone(),
                    gap: f.gap,
                    score: (chi2 - f.chi2) / tau - k * effective.ln(),
                    parameters: json_values(&f.values),
                };
                (s, f)
            })
            .collect();
        last_round = (
            tau,
            scored
                .iter()
                .map(|(s, f)| (s.score, (*f).clone()))
                .collect(),
        );
        let best = scored
            .iter()
            .filter(|(s, f)| s.score > 0.0 && f.gap < (1.0 - MIN_IMPROVEMENT) * gap)
            .max_by(|a, b| a.0.score.total_cmp(&b.0.score));
        let Some((_, winner)) = best else {
            rejected = scored.iter().map(|(s, _)| s.clone()).collect();
            final_effective = effective;
            break if gap <= NOISE_FLOOR_GAP {
                format!("the model explains the data within their noise (gap {gap:.2}, noise floor 1); no effect adds more than its complexity price")
            } else {
                format!(
                    "no candidate effect lowers the gap ({gap:.2}) by more than {:.0} % and its complexity price",
                    MIN_IMPROVEMENT * 100.0
                )
            };
        };
        let brings: Vec<hbmodel::Effect> = match (winner.kind, winner.effect) {
            (effects::StepKind::Add, Some(e)) => e
                .spec()
                .requires
                .iter()
                .copied()
                .filter(|r| !model.has(*r))
                .collect(),
            _ => Vec::new(),
        };
        steps.push(Step {
            kind: winner.kind,
            effect: winner.effect.map(|e| e.name().to_string()),
            name: winner.name.clone(),
            brings: brings.iter().map(|e| e.name().to_string()).collect(),
            parameters: json_values(&winner.values),
            gap_before: gap,
            gap_after: winner.gap,
            candidates: scored.iter().map(|(s, _)| s.clone()).collect(),
            effective_samples: effective,
            preference: evidence::preference(
                &scored
                    .iter()
                    .map(|(s, _)| (s.effect.clone(), s.score))
                    .collect::<Vec<_>>(),
            ),
        });
        model = winner.params.clone();
        // later fits re-adjust what came in; brought-along effects stay at their
        // built-in sizes (re-fitting them too made each later fit 4-parametric with
        // the slow passage dynamics: 480 CPU s for one record, measured)
        // a recalibrated parameter is carried too, within its recalibration bounds
        carried.extend(winner.fitted.iter().copied());
        gap = winner.gap;
        loc = localise(m, e, &simulate(&model, e, m)?, &noise);
    };
    let after = simulate(&model, e, m)?;
    let advice = advice::after(
        &model,
        &steps,
        &rejected,
        gap,
        &last_round,
        &noise,
        progress,
    );
    Ok(Outcome {
        steps,
        initial_gap,
        remaining_gap: gap,
        noise,
        model,
        start: start.clone(),
        first,
        last: loc,
        before,
        after,
        verdict,
        rejected,
        effective_samples: final_effective,
        advice,
    })
}

/// `hbench gap`.
pub fn main(
    data: &Path,
    experiment: &Path,
    model: Option<&Path>,
    out: &Path,
    recalibrate_within: f64,
) -> Result<(), String> {
    if !(0.0..1.0).contains(&recalibrate_within) {
        return Err(format!(
            "--recalibrate-within {recalibrate_within}: a fraction in [0, 1) is expected"
        ));
    }
    let e = load_experiment(experiment)?;
    let m = load_measured(data, &e)?;
    let start = match model {
        Some(f) => Params::load(f).map_err(|err| err.to_string())?,
        None => Params::default(),
    };
    std::fs::create_dir_all(out)
        .map_err(|err| format!("cannot create {}: {err}", out.display()))?;
    let fitted = out.join("fitted_model.toml");
    let inputs: Vec<PathBuf> = [Some(data), Some(experiment), model]
        .into_iter()
        .flatten()
        .filter_map(|p| p.canonicalize().ok())
        .collect();
    for f in ["fitted_model.toml", "report.json", "report.md"] {
        let target = out.join(f);
        if target.canonicalize().is_ok_and(|t| inputs.contains(&t)) {
            return Err(format!(
                "{} is an input: choose another --out",
                target.display()
            ));
        }
    }
    let outcome = run_with(&start, &e, &m, true, recalibrate_within)?;
    std::fs::write(&fitted, outcome.model.to_toml())
        .map_err(|err| format!("cannot write {}: {err}", fitted.display()))?;
    report::write(out, &outcome, &e, &m)?;
    for step in &outcome.steps {
        println!(
            "{} {}: gap {:.2} -> {:.2} ({})",
            match step.kind {
                effects::StepKind::Add => "added",
                effects::StepKind::Recalibrate => "recalibrated",
            },
            step.name,
            step.gap_before,
            step.gap_after,
            step.parameters
                .iter()
                .map(|(k, v)| format!("{k} = {v}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    println!("{}", outcome.verdict);
    if let Some(a) = &outcome.advice {
        println!("what to measure next: {}", a.recommendation);
    }
    println!(
        "wrote {0}/report.md, {0}/report.json, {0}/fitted_model.toml and the figures",
        out.display()
    );
    Ok(())
}
