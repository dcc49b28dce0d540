//! What the record cannot show (issue 14 item 6, its second case): when the model
//! explains a record within its noise, every missing effect the record could not have
//! shown is still possible. Each candidate effect not in the model is switched on at the
//! middle of its plausible range and simulated under the record's own drive; those that
//! would change the record by less than ln B 3 are the record's blind spots, and the
//! designs are assessed for showing each of them against the model as it stands.

use hbmodel::Params;

use super::super::effects::{self, Candidate, StepKind};
use super::super::experiments::designs;
use super::super::fit::Target;
use super::refit::Refit;
use super::{assess, recommend, Advice, Scale};
use crate::gap::evidence::CLEAR_LN_BAYES;
use nalgebra::DVector;
use rayon::prelude::*;

/// `c` switched on in `model` (with what it requires) at the middle of each drawn
/// parameter's plausible range (geometric for the log-scaled ones); the others at the
/// model's values, as `hide` leaves them.
fn at_plausible_middle(model: &Params, c: &Candidate) -> Option<Params> {
    let e = c.effect?;
    let mut p = model.clone();
    p.effects.set(e, true);
    for &r in e.spec().requires {
        p.effects.set(r, true);
    }
    for f in c.fitted.iter().filter(|f| f.drawn) {
        let [lo, hi] = f.plausible;
        let v = if f.log {
            (lo * hi).sqrt()
        } else {
            0.5 * (lo + hi)
        };
        hbmodel::params::param(f.path)?; // an unregistered path: no such model
        super::super::recalibrate::set_fitted(&mut p, f.path, v);
    }
    Some(p)
}

/// The candidate effects `target`'s records cannot show against `model` at their
/// plausible sizes: (name, the model with it, expected ln B on the records). What a
/// recalibration of `model` takes up of an effect's change to the records is no sign of
/// it (`refit`): 0.23 % of entrained air on the Rust bench's +-10 mm steps at 210 bar
/// changes them by ln B 298 raw and by 3.0 once the bulk modulus is re-fitted (measured,
/// form error seed 1), and no analysis of such a record named the air.
pub fn blind_spots(model: &Params, target: &Target, tau: f64) -> Vec<(String, Params, f64)> {
    let Some(base) = target.residuals(model) else {
        return Vec::new();
    };
    // the recalibrations open in the model, read on the records (index 0 is the model)
    let refit = Refit::new(model, &[]);
    // each model's simulations are independent: side by side on the cores, as the
    // advice's designs are (`assess`)
    let runs: Vec<Option<DVector<f64>>> = refit
        .models
        .par_iter()
        .map(|p| target.residuals(p))
        .collect();
    // rayon's collect keeps the candidates' order
    missing(model)
        .into_par_iter()
        .filter_map(|(name, p)| {
            // residuals against the same data: their difference is what the effect changes
            let r = target.residuals(&p)?;
            let left = refit.refit_to(&r, &base, None, &[], &runs);
            let ln_b = left / (2.0 * tau.max(1.0));
            Some((name, p, ln_b))
        })
        .filter(|(_, _, ln_b)| *ln_b < CLEAR_LN_BAYES)
        .collect()
}

/// Each candidate effect not in `model`, switched on at its plausible middle.
fn missing(model: &Params) -> Vec<(String, Params)> {
    effects::all()
        .into_iter()
        .filter(|c| c.kind == StepKind::Add && c.effect.is_some_and(|e| !model.has(e)))
        .filter_map(|c| Some((c.name(), at_plausible_middle(model, &c)?)))
        .collect()
}

/// The models `blind_spots` simulates under the records: the model, the recalibrations'
/// steps and every effect not in `model`.
pub fn searched(model: &Params) -> usize {
    Refit::new(model, &[]).models.len() + missing(model).len()
}

/// The leading models of `check`: the model as it stands and its blind spots.
fn leading(model: &Params, spots: Vec<(String, Params, f64)>) -> Vec<(String, Params)> {
    std::iter::once((super::AS_IS.to_string(), model.clone()))
        .chain(spots.into_iter().map(|(n, p, _)| (n, p)))
        .collect()
}

/// The models `check` simulates under every design (`assess`): the leading models and
/// the steps of the refit that reads them, counted by the model whose cost each has
/// (`Refit::costed`).
pub fn models(model: &Params, spots: &[(String, Params, f64)]) -> Vec<(Params, usize)> {
    let leading = leading(model, spots.to_vec());
    Refit::new(model, &leading).costed(model, &leading)
}

/// The advice for a record explained within its noise: which design would show `spots`,
/// the effects it cannot (`blind_spots`; None when there are none).
pub fn check(
    model: &Params,
    spots: Vec<(String, Params, f64)>,
    noise: &[(&'static str, f64)],
    scale: Scale,
    progress: bool,
) -> Option<Advice> {
    if spots.is_empty() {
        return None;
    }
    let names: Vec<String> = spots
        .iter()
        .map(|(n, _, b)| format!("`{n}` (ln B {b:.1})"))
        .collect();
    let leading = leading(model, spots);
    // every pair: a record of the design is to show each effect against the model as it
    // stands (an analysis afresh) and to tell them apart (the decision between them,
    // `gap --between`); the pair between two unseen effects is no easier (the Rust moves,
    // form error, the volume and the air: as is against the air ln B 298, the volume
    // against the air 5112 on the +-10 mm steps, but 1255 against 1769 on the 50 bar
    // steps, where their compliances both grow)
    let assessed = assess(model, &leading, noise, scale, &designs(), progress);
    let mut advice = recommend(model, &leading, scale, assessed);
    advice.question = format!(
        "the model explains the data within their noise, but the record could not have shown {} at plausible sizes",
        names.join(", ")
    );
    Some(advice)
}
