//! `hbench gap`: compare the model with measured data, find where they disagree, name the
//! missing physical effect, add it with fitted parameters and show the gap shrink; repeat
//! until the data are explained within their noise or no candidate helps.
//!
//! The gap is the RMS of the differences between measured and simulated samples of y, P1
//! and P2, each in units of its own noise level (estimated from the data): 1 is the noise
//! floor. A candidate effect wins when its fit lowers the chi-square (the sum of squared
//! normalised differences) enough to pay the Bayesian information criterion's price of
//! its parameters, counted in the residual's independent samples N / tau and with the
//! misfit's own scale (`evidence::score`: a coloured residual is worth fewer independent
//! samples than it has, and a model far from the data is judged against its misfit, not
//! against the sensor noise), and by more than MIN_IMPROVEMENT of the gap.

pub mod advice;
pub mod analysis;
pub mod blind;
pub mod budget;
pub mod common_delay;
pub mod data;
pub mod decision;
pub mod drive;
pub mod effects;
pub mod evidence;
pub mod experiments;
pub mod fit;
pub mod hide;
pub mod holdout;
pub mod noise;
pub mod oscillation;
pub mod peer;
pub mod recalibrate;
mod report;
pub mod resonance;
mod revision;
mod search;
mod selection;
mod sensor_lag;
pub mod signals;
pub mod variants;

#[cfg(test)]
pub(crate) mod tests;

use std::path::{Path, PathBuf};

use hbmodel::Params;
use serde::Serialize;

use analysis::{localise, quantum, Localisation};
pub use data::{load_records, Record};
use data::{Experiment, Measured, COMPARED};
use drive::{simulate, Traces};
use fit::{Fit, Target};
use noise::noise;

/// A gap at or below this is reported as the noise floor: the noise estimate itself is
/// uncertain by a few percent. The candidates are still tried there: an effect that is
/// small against the noise can still pay its information-criterion price.
pub const NOISE_FLOOR_GAP: f64 = 1.1;
/// The least relative improvement of the gap for which an effect is worth adding, on top
/// of its information-criterion price: a guard against the residual's samples not being
/// as independent as the criterion assumes.
pub const MIN_IMPROVEMENT: f64 = 0.01;
/// At most this many effects are added in one run. Recalibrations are not counted: each
/// parameter is re-fitted at most once (`recalibrate::candidates` leaves out those done),
/// so they end by themselves. Counting them let four recalibrations end the run on the
/// Rust bench with form error before a hidden dry friction or payload was tried again
/// (steps, seed 1: "stopped after 4 effects" with the gap at 1.25 and 2.18, measured).
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
    /// Every candidate's fitted gap and score (`evidence::score`).
    pub candidates: Vec<Scored>,
    /// Independent samples the residual before this step was worth (N / tau).
    pub effective_samples: f64,
    /// How strongly the data prefer this effect over the runner-up.
    pub preference: Option<evidence::Preference>,
    /// The added effect fitted without part of the data, judged on that part (`holdout`).
    pub validation: Option<holdout::Validation>,
    /// How well the record pins each parameter the step fitted (`fit::spread`); empty
    /// for a step re-fitted before a re-ask.
    pub spread: Vec<fit::Spread>,
    /// Each signal's gap before and after the step (`signals`).
    pub signals: Vec<signals::SignalGap>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Scored {
    pub effect: String,
    pub gap: f64,
    pub score: f64,
    pub parameters: serde_json::Map<String, serde_json::Value>,
    /// A fitted parameter that ended on a bound of its fit, with its value.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub on_bound: Option<(&'static str, f64)>,
    /// Every fitted parameter that ended on a bound (`fit::Fit::bounded`; `on_bound` is
    /// the first): a question holds a recalibration every candidate pinned.
    #[serde(skip)]
    pub bounded: Vec<&'static str>,
    /// The signals the fit took further from the data while it brought others closer
    /// (`signals::Baseline::traded`). Reported, not judged: under a lag of the pressure
    /// sensors even the hidden effect's fit trades (`signals`, session 29).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trades: Option<String>,
}

impl Scored {
    /// `f` scored against the model before it, `before`: a residual of `misfit`, each
    /// record's chi-square and independent samples (`evidence::Misfit::score`).
    fn of(f: &Fit, misfit: &evidence::Misfit, before: &signals::Baseline) -> Scored {
        let bounded = f.bounded();
        // the price of the parameters it adds: the carried ones, re-fitted beside them,
        // were fitted in the model `chi2` is of (nested models, `evidence::score`)
        let own = f.values.len().saturating_sub(f.carried.len());
        Scored {
            effect: f.name.clone(),
            gap: f.gap,
            score: misfit.score(&f.by_record(), own as f64),
            parameters: json_values(&f.values),
            on_bound: bounded.first().copied(),
            bounded: bounded.iter().map(|(p, _)| *p).collect(),
            trades: before.traded(&f.signal_gaps),
        }
    }

    /// (name, score) of the candidates a preference is read between: a fit that ended on
    /// a bound is no model the data support, so it is nobody's rival; nor is a fit that
    /// is the same model as another contender (`evidence::same_model`), of which the
    /// recalibration is kept (the account without a new effect, as `selection::choose`
    /// takes it). On the peer's chirp with a hidden manifold volume the SV2
    /// recalibration and `valve_asymmetry` ended at one model, and their "cannot tell"
    /// made the advice look for a design to separate a model from itself (expected ln B
    /// 0.00 under every design, measured).
    fn contenders(scored: &[Scored]) -> Vec<(String, f64)> {
        let fair: Vec<&Scored> = scored.iter().filter(|s| s.on_bound.is_none()).collect();
        fair.iter()
            .filter(|s| {
                !fair.iter().any(|t| {
                    !std::ptr::eq(**s, *t)
                        && evidence::same_model(&s.parameters, &t.parameters)
                        && (s.adds_effect(), t.score) > (t.adds_effect(), s.score)
                })
            })
            .map(|s| (s.effect.clone(), s.score))
            .collect()
    }

    /// It adds a registry effect (not a recalibration, named by the path it re-fits).
    fn adds_effect(&self) -> bool {
        hbmodel::Effect::from_name(&self.effect).is_some()
    }

    /// It pays its price and lowers the gap `before` by more than MIN_IMPROVEMENT; an
    /// added effect also clears `evidence::ADD_LN_BAYES` over the model without it.
    fn worth_adding(&self, before: f64) -> bool {
        let bar = if self.adds_effect() {
            2.0 * evidence::ADD_LN_BAYES
        } else {
            0.0
        };
        self.score > bar && self.gap < (1.0 - MIN_IMPROVEMENT) * before && self.on_bound.is_none()
    }
}

/// The residual of `model` on `target` record by record (`evidence::Misfit`: each
/// record's chi-square and the independent samples it is worth) and its correlation time
/// tau: a missing effect leaves a coloured residual, whose samples are not independent.
/// Each record's samples at the gap `gap` and tau 1 when the model cannot be simulated.
fn misfit(target: &Target, model: &Params, gap: f64) -> (evidence::Misfit, f64) {
    target.misfit(model).unwrap_or_else(|| {
        let records = target
            .records
            .iter()
            .map(|r| (gap * gap * r.len() as f64, r.len() as f64))
            .collect();
        (evidence::Misfit { records }, 1.0)
    })
}

/// What the workflow found on one record: its gaps and where the model disagreed with it,
/// before and after.
pub struct RecordOutcome {
    pub name: String,
    pub experiment: Experiment,
    pub measured: Measured,
    pub noise: Vec<(&'static str, f64)>,
    pub initial_gap: f64,
    pub remaining_gap: f64,
    pub first: Localisation,
    pub last: Localisation,
    pub before: Traces,
    pub after: Traces,
}

/// The workflow's result.
pub struct Outcome {
    pub steps: Vec<Step>,
    /// Gaps over all records together (every sample weighs the same).
    pub initial_gap: f64,
    pub remaining_gap: f64,
    pub records: Vec<RecordOutcome>,
    /// Compared samples over all records.
    pub samples: usize,
    pub model: Params,
    pub start: Params,
    pub verdict: String,
    /// The last round's candidates, none of which was added: why the workflow stopped.
    pub rejected: Vec<Scored>,
    /// Independent samples the final residual is worth (N / tau).
    pub effective_samples: f64,
    /// Which experiment would tell the leading models apart, when this record cannot.
    pub advice: Option<advice::Advice>,
    /// Effects that won a round but did not improve the data they were not fitted on.
    pub refusals: Vec<holdout::Validation>,
    /// A contested step asked again with the run's later recalibrations, and whether the
    /// run was continued from its answer.
    pub revision: Option<revision::Revision>,
    /// Where the run spent its time, and what its budget left out.
    pub timing: budget::Timing,
}

/// Relative tolerance of every simulation the workflow compares with a record (`hbench
/// gap --rtol`); the records themselves (`hide`) stay at the model's 1e-6.
///
/// Its integration error against rtol 1e-8, measured on the chirp records of item 7
/// (seed 1, form error): the chi-square differences between 13 models around the fitted
/// one (bulk modulus, mass, rated flow, viscous friction and dead volume each within
/// 3 %), which are what the scores read, moved by 13.8 RMS (worst 32) with the
/// manifold's passages and 3.7 (worst 7.7) with the valve lag, against 10.8 and 2.1 at
/// 1e-6, 16.3 and 7.6 at 3e-5 and 46.5 and 10.5 at 1e-4; those differences are 1554
/// and 1983 RMS. At 1e-5 the passages' simulations took half the CPU time of 1e-6
/// (0.87 against 1.68 s), the valve lag's 10 % less. The Rust chirp blind study (12
/// cases, seed 1, form error, advice followed) named the same effect first in every case
/// at 21 % less CPU (docs/gap.md, session 23).
pub const RTOL: f64 = 1e-5;

/// `--rtol` within the registry's bounds of `solver.rtol`.
pub fn check_rtol(rtol: f64) -> Result<(), String> {
    let spec = hbmodel::params::param("solver.rtol").expect("registered");
    let (lo, hi) = (spec.min, spec.max);
    if (lo..=hi).contains(&rtol) {
        Ok(())
    } else {
        Err(format!(
            "--rtol {rtol}: a tolerance in [{lo}, {hi}] is expected"
        ))
    }
}

/// `p` to be simulated at the relative tolerance `rtol`.
pub fn at_rtol(p: &Params, rtol: f64) -> Params {
    let mut q = p.clone();
    q.solver.rtol = rtol;
    q
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

/// How a run is carried out.
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    /// Progress bars on the terminal.
    pub progress: bool,
    /// The base model's parameters may be re-fitted within +-`within` of their known
    /// values (0: no recalibration of them).
    pub within: f64,
    /// Say what to measure next when the record leaves a question (`advice`): up to 27
    /// more simulations, some of a 5 s sweep; blind studies that only score the naming
    /// leave it out.
    pub advise: bool,
    /// Relative tolerance of the workflow's simulations ([`RTOL`]).
    pub rtol: f64,
    /// The search stops once this many effects are in ([`MAX_STEPS`]): fewer bound
    /// the cost when only the first answers are wanted.
    pub max_effects: usize,
    /// Wall seconds the run is held to (`budget`): no phase is started that the time
    /// left cannot hold. None: every phase runs.
    pub budget: Option<f64>,
    /// How several records weigh against each other (`fit::Variance`).
    pub variance: fit::Variance,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            progress: false,
            within: recalibrate::DEFAULT_FRACTION,
            advise: true,
            rtol: RTOL,
            max_effects: MAX_STEPS,
            budget: None,
            variance: fit::Variance::Pooled,
        }
    }
}

/// The records as one fitting target, each with the noise levels its data show.
fn target_of(records: &[Record]) -> Result<Target<'_>, String> {
    let mut parts = Vec::with_capacity(records.len());
    for r in records {
        let noise = noise_levels(&r.measured);
        if noise.is_empty() {
            return Err(format!(
                "{}: the data hold none of y, P1, P2 to compare with",
                r.name
            ));
        }
        parts.push(fit::Record::new(&r.measured, &r.experiment, noise));
    }
    if parts.is_empty() {
        return Err("no record to analyse".into());
    }
    Ok(Target {
        records: parts,
        variance: fit::Variance::Pooled,
    })
}

/// Run the workflow on one or several records fitted jointly.
pub fn run_with(start: &Params, records: &[Record], settings: Settings) -> Result<Outcome, String> {
    let Settings {
        progress,
        within,
        rtol,
        ..
    } = settings;
    let clock = budget::Clock::new(settings.budget);
    let start = &at_rtol(start, rtol);
    let mut target = target_of(records)?;
    target.variance = settings.variance;
    let initial_gap = clock.time(budget::FIRST, None, || target.gap(start));
    let names: Vec<String> = records.iter().map(|r| r.name.clone()).collect();
    let mut search = search::Search::new(&target, &names, start, within, progress);
    search.max_effects = settings.max_effects;
    search.clock = Some(&clock);
    search.run();
    // a step the record could not decide, asked again with what the run learned later
    let revision = revision::reask(&search, within, progress);
    if let Some(revised) = revision.as_ref().and_then(|r| r.kept.clone()) {
        search = revised;
    }
    let search::Search {
        model,
        gap,
        steps,
        rounds,
        refusals,
        recalibrated,
        rejected,
        effective: final_effective,
        verdict,
        ..
    } = search;
    let advice = settings
        .advise
        .then(|| {
            let plan = advice::Plan::of(&model, &steps, gap, &rounds);
            let run = (&rounds[..], gap);
            advice::run(&clock, &model, &plan, run, (&target, records), progress)
        })
        .flatten()
        .map(|mut a| {
            a.recalibrate = decision::open(&a.from, within, &recalibrated, &a.between);
            a
        });
    let outcomes = clock.time("records", None, || {
        records
            .iter()
            .zip(&target.records)
            .map(|(r, part)| describe_record(r, part, start, &model))
            .collect::<Result<Vec<_>, String>>()
    })?;
    Ok(Outcome {
        steps,
        initial_gap,
        remaining_gap: gap,
        records: outcomes,
        samples: target.len(),
        model,
        start: start.clone(),
        verdict,
        rejected,
        effective_samples: final_effective,
        advice,
        refusals,
        revision: revision.map(|r| r.report),
        timing: clock.timing(),
    })
}

/// One record's gaps and localisation under the starting and the final model.
fn describe_record(
    r: &Record,
    part: &fit::Record,
    start: &Params,
    model: &Params,
) -> Result<RecordOutcome, String> {
    let (e, m, noise) = (&r.experiment, &r.measured, &part.noise);
    let before = simulate(start, e, m)?;
    let after = simulate(model, e, m)?;
    let alone = Target {
        records: vec![fit::Record::new(m, e, noise.clone())],
        variance: fit::Variance::Pooled,
    };
    Ok(RecordOutcome {
        name: r.name.clone(),
        experiment: e.clone(),
        measured: m.clone(),
        noise: noise.clone(),
        initial_gap: alone.gap(start),
        remaining_gap: alone.gap(model),
        first: localise(m, e, &before, noise),
        last: localise(m, e, &after, noise),
        before,
        after,
    })
}

/// `hbench gap`: `settings` carries the recalibrations' reach (`within`) and the
/// simulations' tolerance (`rtol`); a terminal shows the progress bars.
pub fn main(
    data: &[PathBuf],
    experiments: &[PathBuf],
    model: Option<&Path>,
    out: &Path,
    settings: Settings,
    between: &[String],
    recalibrate: &[String],
) -> Result<(), String> {
    let Settings {
        within: recalibrate_within,
        rtol,
        ..
    } = settings;
    check_rtol(rtol)?;
    budget::check(settings.budget)?;
    if !(0.0..1.0).contains(&recalibrate_within) {
        return Err(format!(
            "--recalibrate-within {recalibrate_within}: a fraction in [0, 1) is expected"
        ));
    }
    let records = load_records(data, experiments)?;
    let start = match model {
        Some(f) => Params::load(f).map_err(|err| err.to_string())?,
        None => Params::default(),
    };
    // the file's own tolerance stays in the fitted model it leads to
    let file_rtol = start.solver.rtol;
    let set_apart = file_rtol != Params::default().solver.rtol && file_rtol != rtol;
    if let Some(f) = model.filter(|_| set_apart) {
        eprintln!(
            "note: {}: solver.rtol = {file_rtol:e} is kept in fitted_model.toml; the workflow simulates at --rtol {rtol:e}",
            f.display()
        );
    }
    std::fs::create_dir_all(out)
        .map_err(|err| format!("cannot create {}: {err}", out.display()))?;
    let fitted = out.join("fitted_model.toml");
    let inputs: Vec<PathBuf> = data
        .iter()
        .chain(experiments)
        .map(PathBuf::as_path)
        .chain(model)
        .filter_map(|p| p.canonicalize().ok())
        .collect();
    let names: Vec<&str> = records.iter().map(|r| r.name.as_str()).collect();
    let outputs = if between.is_empty() {
        report::outputs(&names)
    } else {
        decision::OUTPUTS.map(String::from).to_vec()
    };
    for f in outputs {
        let target = out.join(&f);
        if target.canonicalize().is_ok_and(|t| inputs.contains(&t)) {
            return Err(format!(
                "{} is an input: choose another --out",
                target.display()
            ));
        }
    }
    if !between.is_empty() {
        if settings.variance != fit::Variance::Pooled {
            // a decision scores its candidates as the run before it did, pooled
            return Err(
                "--record-variance applies to the workflow's run, not to a --between \
                        decision, which pools its records"
                    .into(),
            );
        }
        return decision::main(
            &start,
            between,
            recalibrate,
            &records,
            recalibrate_within,
            rtol,
            out,
        );
    }
    let (wall, cpu) = (
        std::time::Instant::now(),
        crate::bench::cpu::process_seconds(),
    );
    let outcome = run_with(&start, &records, settings)?;
    std::fs::write(&fitted, at_rtol(&outcome.model, file_rtol).to_toml())
        .map_err(|err| format!("cannot write {}: {err}", fitted.display()))?;
    report::write(out, &outcome, model)?;
    if model.is_none() {
        println!(
            "started from {}",
            report::start_note(None, &start).replace("**", "")
        );
    }
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
        if a.best.is_some() && !a.between.is_empty() {
            println!(
                "then decide on its record: hbench gap --data NEW.csv --experiment NEW.toml --model {} --between {}{}",
                out.join(advice::QUESTION_MODEL).display(),
                a.between.join(","),
                advice::recalibrate_option(a)
            );
        }
    }
    println!(
        "wrote {0}/report.md, {0}/report.json, {0}/fitted_model.toml and the figures",
        out.display()
    );
    // issue 14 item 7 asks a 2 s record analysed in 60 s on two cores: the user sees both
    // clocks (CPU counts every thread, wall what the other work on the machine left)
    println!(
        "analysed in {:.1} s ({:.1} s of CPU on {} cores)",
        wall.elapsed().as_secs_f64(),
        crate::bench::cpu::process_seconds() - cpu,
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    Ok(())
}
