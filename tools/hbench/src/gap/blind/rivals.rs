//! Identifiability against rivals: can the record tell the hidden effect from every other
//! candidate and every recalibration the workflow may take instead?
//!
//! `visibility` asks only whether the truth differs from the bench without the hidden
//! effect by more than the noise. That called 1.94 % entrained air identifiable on +-10 mm
//! steps, which the steps cannot tell from an oil 3 % softer (ln B 1.4 on the record, CI's
//! `air_on_steps_is_told_from_a_softer_oil_by_the_advised_record`): naming the air first
//! there is a coin toss, not a skill the study should count on.
//!
//! Here the known model is first recalibrated to the bench without the hidden effect
//! (every recalibration at once, noise-free records): where the workflow stands once
//! the form error's parameters are taken up. The hidden effect's signature (what the
//! bench records with it less what it records without it, both with the bench's form
//! error, noise-free) is put on that model's own noise-free record; each rival (every
//! other candidate effect, every recalibration of the known model, all of them at once)
//! is fitted to it from that model, as is the hidden effect itself. On the model's own
//! bench without form error the transplanted record is the bench's record itself. The
//! signature moves with the bench it is measured on, so the farther the bench from the
//! model, the less a transplant is the record: the peer's 1.7 ms sensor delay was
//! reproduced by the model's own delay only to a gap of 9.8 from the known model and 9.0
//! from the recalibrated one (steps, seed 1; the peer's steps differ from the model's by
//! a gap of 33 before recalibration and 6.8 after). Fitted on the bench's own record instead, the
//! rivals would be judged on how much of the form error they take up: an internal leakage
//! 130 times the thesis's (steps, seed 1) left a gap of 2.5 there against 1.4 for SV1's
//! rated flow recalibrated, which took up the form error's 3 % flow error.
//!
//! Beside each model's residual on the transplanted record stands the form error's own
//! (`form_residual`), which every record of the bench carries. Expected evidence: with it
//! and white noise of the sensors' sigma, a model of residual r has chi-square
//! C = |r|^2 + |f|^2 + N in expectation (cross terms left out, see below), and the score difference of `evidence::score`
//! between the hidden effect (C_h, k_h parameters) and a rival (C_r, k_r) is
//! N_eff ln(C_r / C_h) - (k_h - k_r) ln N_eff; ln B is half of it. N_eff is N over the
//! correlation time of the hidden effect's r + f with unit white noise added (seeded).
//! The hidden effect is told from its rivals when ln B clears CLEAR_LN_BAYES in 9
//! records of 10 (`Rivalry::told`).
//!
//! This uses the workflow's own model and optimiser as the ideal fitter, so a fit that
//! fails to find the hidden effect counts against it; the truth at its drawn size in the
//! known model is scored beside the fit, and the better of the two is kept.

use hbmodel::effects::Effect;
use hbmodel::sensors::SensorParams;
use nalgebra::DVector;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};

use super::super::data::{Experiment, Measured, COMPARED};
use super::super::effects::{self, Candidate, StepKind};
use super::super::evidence::{self, CLEAR_LN_BAYES};
use super::super::fit::{fit, Record, Target};
use super::super::hide::{measure_truth, with_hidden, Kind, Truth};
use super::super::recalibrate::{self, DEFAULT_FRACTION};
use super::super::variants::Simulator;
use super::{Case, Setup};

/// How the hidden effect fares against its closest rival on the noise-free record.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Rivalry {
    /// Gap of the hidden effect's best fit (or of the truth at its drawn size, when
    /// better) on the noise-free record, in units of the sensor noise.
    pub hidden_gap: f64,
    /// The rival whose fit comes closest in expected evidence, and its gap.
    pub rival: String,
    pub rival_gap: f64,
    /// Gap the bench's form error leaves once every recalibration is re-fitted
    /// (`form_residual`): it stands beside every model's misfit on the bench's record.
    #[serde(default)]
    pub form_gap: f64,
    /// Expected ln Bayes factor of the hidden effect over that rival at the record's noise,
    /// and its standard deviation from one noise draw to the next.
    pub ln_bayes: f64,
    #[serde(default)]
    pub ln_bayes_sd: f64,
}

/// One-sided normal quantile of the rate the issue asks of the workflow (the hidden effect
/// named first in 90 % of the identifiable cases): a case counts as told when its ln B
/// clears CLEAR_LN_BAYES in 9 noise draws of 10.
pub(super) const TOLD_QUANTILE: f64 = 1.2816;

impl Rivalry {
    /// The record tells the hidden effect from every rival, in 9 records of 10: the
    /// workflow takes a recalibration within ln B 3 of an effect (`selection::choose`),
    /// so an ideal analyst names the effect first only when its ln B clears 3. 1.94 % air
    /// on +-10 mm steps is ln B 4.0 +- 2.8 from a 3 % softer oil: 64 % of records clear
    /// 3 (the CI record found 1.4), so it is not told.
    pub fn told(&self) -> bool {
        self.margin() >= CLEAR_LN_BAYES
    }

    /// The ln B the hidden effect clears in 9 records of 10.
    pub(super) fn margin(&self) -> f64 {
        self.ln_bayes - TOLD_QUANTILE * self.ln_bayes_sd
    }
}

/// Seed of the white noise added to the hidden effect's residual to estimate its
/// correlation time: any fixed value; it only makes the estimate repeatable.
pub(super) const TAU_NOISE_SEED: u64 = 17;

/// The candidate that stands for `e` from `known`: the effect added, or, when the known
/// model has it on already (the section 4.4 leakage and friction), its recalibration.
pub(super) fn standing_for(known: &hbmodel::Params, e: Effect) -> Option<Candidate> {
    if known.has(e) {
        recalibrate::candidates(known, DEFAULT_FRACTION, &[])
            .into_iter()
            .find(|c| c.effect == Some(e))
    } else {
        effects::candidate(e)
    }
}

/// The sensors without their noise: what a judgement reads (its records are the
/// expectation; the noise enters through N and the spread of ln B).
fn noise_free() -> SensorParams {
    SensorParams {
        position_noise: 0.0,
        pressure_noise: 0.0,
        ..SensorParams::default()
    }
}

/// The noise-free records of the bench `truth` under each of `kinds`.
pub(super) fn noise_free_records(
    truth: &Truth,
    kinds: &[Kind],
) -> Result<Vec<(Experiment, Measured)>, String> {
    let exact = noise_free();
    kinds
        .iter()
        .map(|&k| measure_truth(truth, k, &exact))
        .collect()
}

/// The noise-free record of the model `base` under `kind` with the hidden effect's
/// signature added: what the bench records with the effect less what it records without
/// it (both with its form error). A rival is judged on how well it mimics the effect, not
/// on how much of the form error it takes up (see the module's note).
fn transplanted(
    s: &Setup,
    base: &hbmodel::Params,
    kind: Kind,
    exact: &SensorParams,
) -> Result<(Experiment, Measured), String> {
    let (experiment, mut m) = measure_truth(&Truth::rust(base.clone()), kind, exact)?;
    let (_, with) = measure_truth(&s.bench, kind, exact)?;
    let (_, without) = measure_truth(&s.without, kind, exact)?;
    for c in COMPARED {
        let (Some(x), Some(a), Some(b)) = (m.columns.get_mut(c), with.get(c), without.get(c))
        else {
            continue;
        };
        if a.len() != x.len() || b.len() != x.len() {
            return Err(format!(
                "{c}: the bench's records ({} and {} samples) do not match the model's ({})",
                a.len(),
                b.len(),
                x.len()
            ));
        }
        for ((x, a), b) in x.iter_mut().zip(a).zip(b) {
            *x += a - b;
        }
    }
    Ok((experiment, m))
}

/// The fitting target of noise-free records, each signal weighed by the sensors' noise.
pub(super) fn target_of(records: &[(Experiment, Measured)]) -> Target<'_> {
    let noise = SensorParams::default();
    Target {
        records: records
            .iter()
            .map(|(x, m)| {
                let sigmas = COMPARED
                    .iter()
                    .filter(|&&c| m.get(c).is_some())
                    .map(|&c| {
                        let sigma = if c == "y" {
                            noise.position_noise
                        } else {
                            noise.pressure_noise
                        };
                        (c, sigma)
                    })
                    .collect();
                Record::new(m, x, sigmas)
            })
            .collect(),
        variance: Default::default(),
    }
}

/// What the bench's form error leaves of the known model's fit to the bench without the
/// hidden effect once every recalibration is re-fitted at once, and that recalibrated
/// model: the residual no candidate removes, which every record of the bench carries
/// beside the hidden effect. The workflow scores a candidate against the misfit it leaves
/// (`evidence::score`), so a small effect's signature is lost beside a large form error:
/// an internal leakage 27 times the thesis's (steps, seed 2, a 0.46 ms pressure-sensor
/// lag) was told from SV1's rated flow by ln B 37 +- 9 on its signature alone, from the
/// known model, and was not named; recalibrated first and with this residual beside it,
/// it is a null bias of the valves (ln B 0.0).
fn form_residual(
    target: &Target,
    known: &hbmodel::Params,
) -> Result<(hbmodel::Params, DVector<f64>), String> {
    let f = fit(target, known, &every_recalibration(known, None), &[]);
    let r = target
        .residuals(&f.params)
        .ok_or("the known model, recalibrated, fails on the bench's record")?;
    Ok((f.params, r))
}

/// What a rival re-fitting every parameter at once is called.
pub(super) const EVERY: &str = "every recalibration at once";

/// Every recalibration of `known` as one candidate (SV2 as its own valve among them): the
/// known model bent as far as its parameters' bounds let it. As a rival it leaves out the
/// parameters of the hidden effect `except` (the section 4.4 leakage and friction are on
/// in the known model, and recalibrating them is naming them). It is a rival because
/// recalibrations taken one after the other can take up an effect: on seed 1's steps an
/// internal leakage 130 times the thesis's, told by ln B 85 from the best single
/// recalibration, went unnamed once SV1's rated flow, the moving mass and the bulk modulus
/// had been recalibrated (gap 2.37 -> 1.20; the leakage would then have lowered it to
/// 1.198). On the transplanted record it does not come closer than the single ones there
/// (measured): the form error those recalibrations took up is not on it.
pub(super) fn every_recalibration(known: &hbmodel::Params, except: Option<Effect>) -> Candidate {
    let own =
        |c: &Candidate| except.is_some_and(|e| c.effect == Some(e) || c.switches_on.contains(&e));
    let open: Vec<Candidate> = recalibrate::candidates(known, DEFAULT_FRACTION, &[])
        .into_iter()
        .filter(|c| !own(c))
        .collect();
    // SV2 re-fitted apart from SV1 is its own valve: the peer's SV2 is drawn 5 % off its
    // SV1, and without it the peer's form error read as a gap of 28 (steps, seed 1)
    let switches_on = open
        .iter()
        .find(|c| !c.switches_on.is_empty())
        .map_or(&[][..], |c| c.switches_on);
    Candidate {
        kind: StepKind::Recalibrate,
        effect: None,
        fitted: open.into_iter().flat_map(|c| c.fitted).collect(),
        signature: EVERY,
        switches_on,
    }
}

/// Judge the single hidden effect of a case's bench against its rivals on the
/// noise-free records of `kinds`. None for pairs and for nothing hidden.
pub fn rivalry(
    s: &Setup,
    hidden: &[Effect],
    kinds: &[Kind],
    progress: bool,
) -> Result<Option<Rivalry>, String> {
    let [e] = hidden else { return Ok(None) };
    let known = &s.known;
    let Some(own) = standing_for(known, *e) else {
        return Ok(None);
    };
    let exact = noise_free();
    let without = noise_free_records(&s.without, kinds)?;
    // the known model recalibrated to the bench without the effect: where the workflow
    // stands once the form error's parameters are taken up, and what is left of it
    let (base, form) = form_residual(&target_of(&without), known)?;
    let records: Vec<(Experiment, Measured)> = kinds
        .iter()
        .map(|&k| transplanted(s, &base, k, &exact))
        .collect::<Result<_, _>>()?;
    let target = target_of(&records);
    // every other effect the workflow may add, and every recalibration but the hidden
    // effect's own
    let mut candidates: Vec<Candidate> = effects::all()
        .into_iter()
        .filter(|c| c.effect.is_some_and(|x| x != *e && !known.has(x)))
        .chain(
            recalibrate::candidates(known, DEFAULT_FRACTION, &[])
                .into_iter()
                .filter(|c| c.effect != Some(*e)),
        )
        .chain(std::iter::once(every_recalibration(known, Some(*e))))
        .collect();
    candidates.insert(0, own);
    let bar = crate::parallel::bar(candidates.len(), "rivals", progress);
    let fits = crate::parallel::map(&candidates, &bar, Candidate::name, |c| {
        fit(&target, &base, c, &[])
    });
    let n = target.len() as f64;
    let (own_fit, rivals) = fits.split_first().expect("the hidden effect's own fit");
    // the truth at its drawn size, in the recalibrated model, beside the fit
    let at_truth = with_hidden(&base, hidden, &s.drawn);
    let (hidden_chi2, hidden_model) = match target.residuals(&at_truth) {
        Some(r) if r.norm_squared() < own_fit.chi2 => (r.norm_squared(), at_truth),
        _ => (own_fit.chi2, own_fit.params.clone()),
    };
    let own = target
        .residuals(&hidden_model)
        .ok_or("the hidden effect's model fails on its own record")?;
    if own.len() != form.len() {
        return Err("the bench's records with and without the effect differ in length".into());
    }
    // each model's residual on the bench's record: its own, with the form error's beside
    let residual = &own + &form;
    // expected chi-squares on the noisy record: the model's own misfit, the form error's
    // and the noise's N. Each fit on the bench's own record would take up part of the
    // form error; fitted without it here, their cross terms with it are chance (an
    // added one put seed 2's dry friction from ln B 57 to -66), so they are left out.
    let form_chi2 = form.norm_squared();
    let expected = Expected::new(
        residual,
        &target.blocks(),
        hidden_chi2 + form_chi2 + n,
        own_fit.values.len() as f64,
    )?;
    let gap = |chi2: f64| (chi2 / n).sqrt();
    // a rival that ended on a narrow bound of its fit is no model the workflow takes; the
    // closest is the one least often beaten clearly
    Ok(rivals
        .iter()
        .filter(|f| f.on_bound().is_none())
        .filter_map(|f| Some((f, target.residuals(&f.params)? + &form)))
        .map(|(f, r)| {
            let c_r = f.chi2 + form_chi2 + n;
            Rivalry {
                hidden_gap: gap(hidden_chi2),
                rival: match f.candidate.kind {
                    StepKind::Add => f.name.clone(),
                    _ if f.candidate.signature == EVERY => EVERY.to_string(),
                    StepKind::Recalibrate => format!("recalibrate {}", f.name),
                },
                rival_gap: f.gap,
                form_gap: gap(form_chi2),
                ln_bayes: expected.ln_bayes(c_r, f.values.len() as f64),
                ln_bayes_sd: expected.sd(&r, c_r),
            }
        })
        .min_by(|a, b| a.margin().total_cmp(&b.margin())))
}

/// The evidence a record is expected to hold for the hidden effect's model (residual
/// `residual`, expected chi-square `c_h` on the noisy record, `k_own` parameters) against
/// a rival's, at the sensors' noise (unit variance in the residual's units).
pub(super) struct Expected {
    residual: DVector<f64>,
    c_h: f64,
    k_own: f64,
    /// Independent samples of the hidden model's residual with unit white noise added
    /// (seeded: the estimate is repeatable), series by series (`blocks`).
    effective: f64,
}

impl Expected {
    pub(super) fn new(
        residual: DVector<f64>,
        blocks: &[usize],
        c_h: f64,
        k_own: f64,
    ) -> Result<Self, String> {
        let mut rng = Pcg64::seed_from_u64(TAU_NOISE_SEED);
        let white = Normal::new(0.0, 1.0).map_err(|x| x.to_string())?;
        let noisy: Vec<f64> = residual
            .iter()
            .map(|r| r + white.sample(&mut rng))
            .collect();
        let (effective, _) = evidence::effective_samples(&noisy, blocks);
        Ok(Expected {
            residual,
            c_h,
            k_own,
            effective,
        })
    }

    /// ln B of the hidden effect's model over a rival of expected chi-square `c_r` with
    /// `k` parameters (`evidence::score`'s form, halved).
    pub(super) fn ln_bayes(&self, c_r: f64, k: f64) -> f64 {
        let eff = self.effective;
        (eff * (c_r / self.c_h).ln() - (self.k_own - k) * eff.ln()) / 2.0
    }

    /// ln B's spread from one noise draw n to the next, for a rival of residual `r`: a
    /// model's chi-square on the noisy record is C = |r + n|^2 = c + N + 2 n.r +
    /// (|n|^2 - N), so ln B moves by N_eff / 2 (2 n.r_r / C_r - 2 n.r_h / C_h + (|n|^2 -
    /// N) (1 / C_r - 1 / C_h)), of variance (N_eff / 2)^2 (4 |r_r / C_r - r_h / C_h|^2 +
    /// 2 N (1 / C_r - 1 / C_h)^2); near the noise floor that is |r_r - r_h| / tau.
    pub(super) fn sd(&self, r: &DVector<f64>, c_r: f64) -> f64 {
        let n = self.residual.len() as f64;
        let apart = (r / c_r - &self.residual / self.c_h).norm_squared();
        self.effective / 2.0 * (4.0 * apart + 2.0 * n * (1.0 / c_r - 1.0 / self.c_h).powi(2)).sqrt()
    }
}

/// A recorded case's bench (from its seed), the effects it hid and the experiments of
/// its records: what either judgement needs to make it again.
pub(super) fn setup_of(case: &Case) -> Result<(Setup, Vec<Effect>, Vec<Kind>), String> {
    let sim = Simulator::parse(&case.simulator)?;
    let hidden = hidden_of(case)?;
    let kinds: Vec<Kind> = case
        .experiment
        .split('+')
        .map(Kind::parse)
        .collect::<Result<_, _>>()?;
    let s = Setup::new(sim, case.form_error, &hidden, case.seed);
    Ok((s, hidden, kinds))
}

/// The effects a case hid, without those they brought along (which `Case::hidden` lists
/// before them).
fn hidden_of(case: &Case) -> Result<Vec<Effect>, String> {
    let all: Vec<Effect> = case
        .hidden
        .iter()
        .map(|h| Effect::from_name(h).ok_or(format!("unknown effect '{h}'")))
        .collect::<Result<_, _>>()?;
    Ok(all
        .iter()
        .copied()
        .filter(|x| !all.iter().any(|o| o.spec().requires.contains(x)))
        .collect())
}

/// Judge a recorded case against its rivals again, from its bench's seed.
pub fn judge(case: &Case, progress: bool) -> Result<Option<Rivalry>, String> {
    let (s, hidden, kinds) = setup_of(case)?;
    rivalry(&s, &hidden, &kinds, progress)
}

/// A judgement of the Rust bench's steps (seed `seed`, with or without form error) with
/// one effect `e` hidden, by `judge` (`rivalry` here or `on_record::rivalry`): the tests'
/// one way to ask either judge.
#[cfg(test)]
pub(super) type JudgeFn = fn(&Setup, &[Effect], &[Kind], bool) -> Result<Option<Rivalry>, String>;

#[cfg(test)]
pub(super) fn on_rust_steps(judge: JudgeFn, form_error: bool, seed: u64, e: Effect) -> Rivalry {
    let s = Setup::new(Simulator::Rust, form_error, &[e], seed);
    judge(&s, &[e], &[Kind::Steps], false)
        .unwrap()
        .expect("a single hidden effect is judged")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The judge on the model's own bench, steps, seed 1 (no form error): the 1.94 % air
    /// is a softer oil to the steps (the workflow found ln B 1.4 between them on the noisy
    /// record, `air_on_steps_is_told_from_a_softer_oil_by_the_advised_record`), so it is
    /// not told; a 1.7 ms sensor delay is, clearly. Without form error the transplanted
    /// record is the bench's own, so the truth in the known model fits it to the
    /// quantisation.
    #[test]
    fn air_on_steps_is_not_told_from_a_softer_oil_but_a_delay_is_told() {
        let judge = |e: Effect| on_rust_steps(rivalry, false, 1, e);
        let air = judge(Effect::EntrainedAir);
        assert!(!air.told(), "{air:?}");
        assert_eq!(air.rival, "recalibrate fluid.bulk_modulus", "{air:?}");
        assert!(air.hidden_gap < 0.3, "{air:?}");
        let delay = judge(Effect::SensorDelay);
        assert!(delay.told() && delay.ln_bayes > 100.0, "{delay:?}");
        assert!(delay.hidden_gap < 0.3, "{delay:?}");
        // without form error what is left is the converters' quantisation (0.026)
        assert!(
            air.form_gap < 0.05 && delay.form_gap < 0.05,
            "no form error: {air:?} {delay:?}"
        );
    }

    /// With a form error (Rust bench, steps, seed 2: a 0.46 ms pressure-sensor lag and
    /// parameters a few percent off) the known model is recalibrated to the bench first,
    /// and the form error's residual then left stands beside each model's: 4.27 noise
    /// levels under the lag as drawn (session 64; 0.95 while the lag acted as 0.13 ms,
    /// docs/gap.md). A 0.31 ms sensor delay stays told, from the entrained air, by
    /// ln B 174 +- 2 (1471 +- 17 under the weak lag); an internal leakage 27 times the
    /// thesis's fits to gap 0.048 against 0.208 for SV1's rated flow, its closest rival,
    /// but by ln B 1.2 +- 0.3 only, not told (measured, session 64; ln B 16.0 +- 3.5 over
    /// SV1's null bias under the weak lag, session 33). Until session 33 it read ln B 0.0
    /// there: the judge's recalibrated model re-fits SV2's flow and bias with the rest,
    /// which makes SV2 its own valve, and the leakage's recalibration then moved SV1's
    /// null leakage alone, while the bench's two valves leak alike
    /// (`recalibrate::set_fitted`).
    #[test]
    fn beside_a_form_error_a_delay_is_told_far_more_clearly_than_a_leakage() {
        let judge = |e: Effect| on_rust_steps(rivalry, true, 2, e);
        let delay = judge(Effect::SensorDelay);
        assert!(delay.told() && delay.ln_bayes > 100.0, "{delay:?}");
        assert!((3.0..6.0).contains(&delay.form_gap), "{delay:?}");
        let leak = judge(Effect::InternalLeakage);
        assert!(!leak.told() && leak.ln_bayes < 10.0, "{leak:?}");
        assert!(leak.hidden_gap < leak.rival_gap, "{leak:?}");
        assert!(leak.rival.starts_with("recalibrate"), "{leak:?}");
        assert_eq!(leak.form_gap, delay.form_gap, "one bench: {leak:?}");
    }
}
