//! What to measure next (issue 14, item 6). When the record cannot tell the leading
//! models apart (the best candidates within ln B 3 of each other, or none accepted while
//! the gap stays above the noise floor), the leading models are simulated, noise-free,
//! under every experiment design the tools know, and the design that separates the
//! closest pair most is recommended, with the separation expected at the record's noise.
//!
//! For two models a and b and a record of n samples of y, P1, P2 with noise sigma, the
//! wrong model's chi-square exceeds the right one's by D = sum(((a - b) / sigma)^2) on
//! average. The right one's is not n: the record's model-form error is on the next
//! record too, and the record showed it as its misfit m (the gap squared, in noise
//! levels). `evidence::score` reads a drop against the misfit, over the N / tau
//! independent samples the residual's correlation time tau leaves, so the expected ln B
//! is (n / tau) / 2 ln(1 + D / (n m)): D / (2 tau) at the noise floor (m = 1). Read
//! against the sensor noise alone, the peer's steps advice expected ln B 59-338 where the
//! records found 0.8-67; against their misfit (7.8-9.5 noise levels RMS) 0.9-4.0, five
//! of six within a factor of 2 of what was found (docs/gap.md, session 21).
//!
//! D is what is left of the difference once each model is re-fitted to the other's run
//! (`refit`: its own parameters and the known model's recalibrations, to first order
//! within their bounds), as the new record's analysis re-fits them. Before it, on the
//! Rust moves with form error, the decisions found 4 to 26 times less than the raw
//! difference promised; with it 2 to 20 times (session 56). It is still an upper bound:
//! a large refit is not linear, the new record brings its own form error (a design at
//! another supply more than one at the record's), and the price of the parameters
//! (k ln(N / tau)) is left out, as between models of equal k. A design the records
//! already hold is read at what they showed (`recorded`): another record of it brings
//! the same form error and the same question.

use hbmodel::Params;
use serde::Serialize;

use super::analysis::sensor_range;
use super::evidence::CLEAR_LN_BAYES;
use super::experiments::Design;
use super::fit::Fit;
use super::hide::{raw, Truth};
use super::{Step, NOISE_FLOOR_GAP};

mod plan;
mod recommendation;
mod recorded;
pub mod refit;
mod validity;
use nalgebra::DVector;
pub use plan::{run, Plan};
use recommendation::recommend;
pub use recommendation::{markdown, recalibrate_option};
use refit::{normalised, Refit};
pub use validity::Simulated;
use validity::{held_ripple, no_evidence, pressure_span};

/// Candidates of the last round compared with the model as it stands: the two best, as
/// the Bayes factor of `evidence` compares the best with the runner-up.
pub const LEADING_CANDIDATES: usize = 2;
/// What the reports call the model as the workflow left it.
pub const AS_IS: &str = "as is";

/// What a new record's evidence is read against: what the record showed of its residual.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Scale {
    /// Correlation time of the residual (samples, at least 1).
    pub tau: f64,
    /// Mean square of the residual in noise levels, the gap squared (at least 1): the
    /// model-form error a new record shows too.
    pub misfit: f64,
}

impl Scale {
    /// The residual of correlation time `tau` and RMS `gap` noise levels.
    pub fn new(tau: f64, gap: f64) -> Scale {
        let tau = if tau.is_finite() { tau.max(1.0) } else { 1.0 };
        let misfit = if gap.is_finite() {
            (gap * gap).max(1.0)
        } else {
            1.0
        };
        Scale { tau, misfit }
    }
}

/// How far apart two leading models come out under one design.
#[derive(Debug, Clone, Serialize)]
pub struct Separation {
    pub a: String,
    pub b: String,
    /// Expected chi-square difference: sum over samples of ((a - b) / sigma)^2.
    pub chi2: f64,
    /// RMS of (a - b) / sigma over the samples: the separation in noise levels.
    pub rms: f64,
    /// The ln B the advice reads the design at: `simulated`, or no more than `recorded`
    /// when the records hold the design.
    pub ln_bayes_factor: f64,
    /// (n / tau) / 2 ln(1 + chi2 / (n misfit)), n the samples compared: what the two
    /// models' simulations promise, kept beside what the records showed.
    pub simulated: f64,
    /// The ln B between the two that the records showed, when they hold this design.
    pub recorded: Option<f64>,
    /// Share of the two runs' chi-square difference a refit takes up (`refit`): `chi2`,
    /// `rms` and the ln B are what is left of it.
    pub absorbed: f64,
}

impl Separation {
    /// The separation once a refit has left `left` of its chi-square (`refit::Refit::left`).
    fn after_refit(&mut self, left: f64, samples: usize, scale: Scale) {
        let left = left.clamp(0.0, self.chi2);
        self.absorbed = if self.chi2 > 0.0 {
            1.0 - left / self.chi2
        } else {
            0.0
        };
        self.chi2 = left;
        let n = samples.max(1) as f64;
        self.rms = (left / n).sqrt();
        self.simulated = expected_ln_bayes(left, n, scale);
        self.ln_bayes_factor = self.simulated;
    }
}

/// (n / tau) / 2 ln(1 + chi2 / (n misfit)): the ln B a chi-square difference `chi2` over
/// `n` samples is expected to show against the record's residual `scale`.
fn expected_ln_bayes(chi2: f64, n: f64, scale: Scale) -> f64 {
    // ln_1p: a separation far below the misfit is chi2 / (2 tau misfit) to the last digit
    n / scale.tau / 2.0 * (chi2 / (n * scale.misfit)).ln_1p()
}

/// One design, assessed.
#[derive(Debug, Clone, Serialize)]
pub struct Assessed {
    pub design: Design,
    pub label: String,
    pub pairs: Vec<Separation>,
    /// Over the pairs: the least expected ln B (None when a simulation failed).
    pub least_ln_bayes_factor: Option<f64>,
    /// Why the design could not be assessed: a simulation that failed, or a leading model
    /// whose run is no evidence under it (`validity`: it oscillates on its own or leaves
    /// the oil's pressure range).
    pub error: Option<String>,
}

/// The advice: the designs assessed and the one recommended.
#[derive(Debug, Clone, Serialize)]
pub struct Advice {
    /// Why the record raised a question: undecided leading models, or effects it cannot
    /// show (`unseen`).
    pub question: String,
    pub leading: Vec<String>,
    /// Correlation time of the record's residual the evidence is divided by.
    pub tau: f64,
    /// The record's misfit (gap squared) a new record's evidence is read against.
    pub misfit: f64,
    pub designs: Vec<Assessed>,
    /// Label of the design that separates the closest pair most.
    pub best: Option<String>,
    /// Whether that design separates every pair (expected ln B >= CLEAR_LN_BAYES) but
    /// the `equivalent` ones.
    pub separates: bool,
    pub recommendation: String,
    /// Pairs of leading models no design separates, left out of the choice when another
    /// pair is separated (`recommendation::equivalent_pairs`).
    pub equivalent: Vec<(String, String)>,
    /// The candidates a record of the recommended design is to decide between
    /// (`decision::decide`): the leading models but the model as it stands.
    pub between: Vec<String>,
    /// The model they are fitted from (written as `question_model.toml`): the model before
    /// the undecided step, or the model as it stands.
    #[serde(skip)]
    pub from: Params,
    /// The known model's parameters the run recalibrated (registry paths) that are open
    /// from `from`: a new record is read with them re-fitted before the candidates are
    /// compared (the first record's form error is on the next one too).
    pub recalibrate: Vec<String>,
}

/// One round of the workflow as the advice needs it: the correlation time of the residual
/// the round started from, and each candidate's score and fit (its gap the misfit).
#[derive(Debug, Clone)]
pub struct Round {
    /// The model the round fitted its candidates from.
    pub start: Params,
    pub tau: f64,
    pub fits: Vec<(f64, Fit)>,
}

/// The candidate a step could not tell from the one it took, if any: the step's
/// preference is no clear one and the rival paid its price too (`rival`).
pub fn contested(step: &Step) -> Option<&str> {
    let p = step.preference.as_ref()?;
    // the verdict's words derive from this number (`evidence::preference`)
    rival(step).filter(|_| p.ln_bayes_factor < CLEAR_LN_BAYES)
}

/// The step's rival when it paid its price: the best scorer, or the runner-up when the
/// step took the best (a recalibration is taken over a close effect,
/// `selection::choose`).
pub fn rival(step: &Step) -> Option<&str> {
    let p = step.preference.as_ref()?;
    let rival = if p.best == step.name {
        &p.runner_up
    } else {
        &p.best
    };
    let paid = step
        .candidates
        .iter()
        .any(|c| &c.effect == rival && c.score > 0.0);
    paid.then_some(rival.as_str())
}

/// Whether the record left something to tell apart: the run stopped above the noise
/// floor (something is missing that no candidate explained on this record, or the run
/// reached its limit of added effects before explaining it), or a step's choice and its
/// rival both paid their price and stood within ln B 3 of each other (two explanations
/// of what the record showed). At the noise floor every rejected candidate scores about
/// -k ln N and any two are within ln B 3; that is no question the data raise, and asking
/// it cost 27 simulations per run (measured on the blind sample).
pub fn needed(steps: &[Step], gap: f64) -> bool {
    steps.iter().any(|s| contested(s).is_some()) || gap > NOISE_FLOOR_GAP
}

/// The model as it stands and the best-scoring candidates of the last round (`round`:
/// score and fit), leaving out `accepted`, the one the model already is, and fits that
/// ended on a bound (no model the data support).
pub fn leading(
    model: &Params,
    round: &[(f64, Fit)],
    accepted: Option<&str>,
) -> Vec<(String, Params)> {
    let mut ranked: Vec<&(f64, Fit)> = round
        .iter()
        .filter(|(s, f)| {
            s.is_finite() && f.on_bound().is_none() && Some(f.name.as_str()) != accepted
        })
        .collect();
    ranked.sort_by(|a, b| b.0.total_cmp(&a.0));
    std::iter::once((AS_IS.to_string(), model.clone()))
        .chain(
            ranked
                .into_iter()
                .take(LEADING_CANDIDATES)
                .map(|(_, f)| (f.name.clone(), f.params.clone())),
        )
        .collect()
}

/// A step the record could not decide.
#[derive(Debug)]
pub struct Undecided {
    /// Index of the step.
    pub step: usize,
    /// Correlation time of the residual its round started from.
    pub tau: f64,
    /// The better gap of its two fits: the misfit neither explained.
    pub gap: f64,
    /// The model before the step.
    pub from: Params,
    /// Its choice and its rival, as fitted in that round.
    pub pair: [(String, Params); 2],
}

/// The earliest contested step.
pub fn earliest_contested(steps: &[Step], rounds: &[Round]) -> Option<Undecided> {
    steps.iter().enumerate().find_map(|(i, s)| {
        let rival = contested(s)?;
        let round = rounds.get(i)?;
        let fit = |name: &str| round.fits.iter().find(|(_, f)| f.name == name);
        let (chosen, other) = (fit(&s.name)?, fit(rival)?);
        let pick = |(_, f): &(f64, Fit)| (f.name.clone(), f.params.clone());
        Some(Undecided {
            step: i,
            tau: round.tau,
            gap: chosen.1.gap.min(other.1.gap),
            from: round.start.clone(),
            pair: [pick(chosen), pick(other)],
        })
    })
}

/// Noise-free y, P1, P2 of `params` under `design`, as the sensors would read them
/// (saturating beyond their span), without their noise and lags: the records `hbench hide`
/// would make of the model, before the noise; with what tells whether the run is evidence
/// (`validity`).
pub fn simulate(params: &Params, design: &Design) -> Result<Simulated, String> {
    let (experiment, rows) = raw(&Truth::rust(params.clone()), design)?;
    let clamp = |name: &str, v: f64| {
        let [lo, hi] = sensor_range(name);
        v.clamp(lo, hi)
    };
    let traces = rows
        .iter()
        .map(|&[_, y, p1, p2, _]| [clamp("y", y), clamp("P1", p1), clamp("P2", p2)])
        .collect();
    Ok(Simulated {
        traces,
        held_ripple: held_ripple(&rows),
        pressures: pressure_span(&rows),
        supply: experiment.supply_pressure,
    })
}

/// Index of a compared signal in `simulate`'s rows.
fn column(signal: &str) -> Option<usize> {
    ["y", "P1", "P2"].iter().position(|s| *s == signal)
}

/// How far apart `a` and `b` come out at the noise levels `noise`, read against `scale`.
pub fn separation(
    (na, a): (&str, &[[f64; 3]]),
    (nb, b): (&str, &[[f64; 3]]),
    noise: &[(&'static str, f64)],
    scale: Scale,
) -> Separation {
    let mut chi2 = 0.0;
    let mut count = 0usize;
    for &(name, sigma) in noise {
        let Some(c) = column(name).filter(|_| sigma > 0.0) else {
            continue;
        };
        chi2 += a
            .iter()
            .zip(b)
            .map(|(x, y)| ((x[c] - y[c]) / sigma).powi(2))
            .sum::<f64>();
        count += a.len().min(b.len());
    }
    let n = count.max(1) as f64;
    let simulated = expected_ln_bayes(chi2, n, scale);
    Separation {
        a: na.to_string(),
        b: nb.to_string(),
        chi2,
        rms: (chi2 / n).sqrt(),
        ln_bayes_factor: simulated,
        simulated,
        recorded: None,
        absorbed: 0.0,
    }
}

/// Simulate the `leading` models under every design (in parallel) and assess how far
/// apart each design sets every pair of them, at the record's `noise`, read against its
/// residual's `scale`, after what a refit from `from` takes up (`refit`).
fn assess(
    from: &Params,
    leading: &[(String, Params)],
    noise: &[(&'static str, f64)],
    scale: Scale,
    designs: &[Design],
    progress: bool,
) -> Vec<Assessed> {
    let refit = Refit::new(from, leading);
    let models: Vec<&Params> = leading
        .iter()
        .map(|(_, p)| p)
        .chain(&refit.models)
        .collect();
    let names: Vec<String> = leading.iter().map(|(n, _)| n.clone()).collect();
    let runs: Vec<(usize, usize)> = (0..designs.len())
        .flat_map(|d| (0..models.len()).map(move |m| (d, m)))
        .collect();
    let bar = crate::parallel::bar(runs.len(), "advising", progress);
    let traces = crate::parallel::map(
        &runs,
        &bar,
        |&(d, m)| {
            let name = names.get(m).map_or("a refit's step", String::as_str);
            format!("{name} under {}", designs[d].label())
        },
        |&(d, m)| simulate(models[m], &designs[d]),
    );
    designs
        .iter()
        .enumerate()
        .map(|(d, design)| {
            let all = &traces[d * models.len()..(d + 1) * models.len()];
            assess_design(
                design,
                &all[..leading.len()],
                all,
                leading,
                noise,
                scale,
                &refit,
            )
        })
        .collect()
}

/// One design: `runs` of the leading models, `all` of them and the refit's steps.
fn assess_design(
    design: &Design,
    runs: &[Result<Simulated, String>],
    all: &[Result<Simulated, String>],
    leading: &[(String, Params)],
    noise: &[(&'static str, f64)],
    scale: Scale,
    refit: &Refit,
) -> Assessed {
    let label = design.label();
    let sims: Result<Vec<&Simulated>, String> = runs
        .iter()
        .map(|r| r.as_ref().map_err(Clone::clone))
        .collect();
    // a leading model whose run is no evidence: its own limit cycle, or pressures
    // outside the oil's range (`validity`)
    let sigma = noise.iter().find(|(n, _)| *n == "P1").map_or(0.0, |x| x.1);
    let invalid = sims.as_ref().ok().and_then(|sims| {
        sims.iter()
            .zip(leading)
            .find_map(|(sim, (name, _))| no_evidence(name, sim, sigma))
    });
    let sims = match (sims, invalid) {
        (Ok(s), None) => s.into_iter().map(|s| &s.traces).collect::<Vec<_>>(),
        (Ok(_), Some(e)) | (Err(e), _) => {
            return Assessed {
                design: *design,
                label,
                pairs: Vec::new(),
                least_ln_bayes_factor: None,
                error: Some(e),
            }
        }
    };
    let vectors: Vec<Option<DVector<f64>>> = all
        .iter()
        .map(|r| r.as_ref().ok().map(|s| normalised(&s.traces, noise)))
        .collect();
    let names: Vec<String> = leading.iter().map(|(n, _)| n.clone()).collect();
    let mut pairs = Vec::new();
    for i in 0..sims.len() {
        for j in i + 1..sims.len() {
            let mut s = separation(
                (&leading[i].0, sims[i]),
                (&leading[j].0, sims[j]),
                noise,
                scale,
            );
            if let Some(left) = refit.left(&vectors, &names, i, j) {
                let samples = vectors[i].as_ref().map_or(0, DVector::len);
                s.after_refit(left, samples, scale);
            }
            pairs.push(s);
        }
    }
    let least = pairs
        .iter()
        .map(|p| p.ln_bayes_factor)
        .min_by(f64::total_cmp);
    Assessed {
        design: *design,
        label,
        pairs,
        least_ln_bayes_factor: least,
        error: None,
    }
}

/// The file the report writes the question's starting model to.
pub const QUESTION_MODEL: &str = "question_model.toml";

#[cfg(test)]
mod tests;
pub mod unseen;
