//! Held-out validation (issue 14 item 2): an effect is added only if, fitted without part
//! of the data, it improves that part.
//!
//! The scores (`evidence::score`) judge a candidate on the data it was fitted on. Under
//! model-form error an effect can lower that misfit by bending itself into the shape of
//! physics the model lacks, and the information criterion, whatever its sample count,
//! cannot tell such a fit from a true one. A fit that learned the record's particulars
//! instead of the bench's physics does not carry over to data it did not see. The folds:
//! a record's first and second halves (a steps record's first and last steps), or, when
//! its drive sweeps in frequency, every other one of its PIECES pieces (`interleaved`);
//! with several records, every record at once by its own folds, and no record may come
//! out clearly worse unless the records together are clearly for the candidate (`folds`,
//! `Fold::contradiction`). The whole record is always simulated: the held-out part's
//! states come from the model running through the fitted part.

use std::cell::OnceCell;

use hbmodel::Params;
use serde::Serialize;

use super::common_delay::{self, SensorSay};
use super::effects::{Candidate, Fitted, StepKind};
use super::evidence::{self, ADD_LN_BAYES, CLEAR_LN_BAYES};
use super::fit::{chi2, fit, Fit, Target};
use super::NOISE_FLOOR_GAP;

mod folds;
#[cfg(test)]
use folds::PIECES;
pub use folds::{folds, Split};

/// One fold: the gap of `held_out` under the model before the step and with the
/// candidate, each fitted on the rest of the data.
#[derive(Debug, Clone, Serialize)]
pub struct Fold {
    pub held_out: String,
    pub gap_before: f64,
    pub gap_after: f64,
    /// With several records, each record's held-out part alone.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub records: Vec<RecordFold>,
    /// With several records, the ln Bayes factor against the candidate on their held-out
    /// parts together (`Fold::together`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ln_bayes_against: Option<f64>,
}

impl Fold {
    /// The ln Bayes factor against the candidate on every record's held-out part of the
    /// fold together: the sum of the records' own. Each record's noise is its own, and
    /// each record's factor is counted in its own independent samples, so their evidence
    /// adds. None with one record.
    pub fn together(records: &[RecordFold]) -> Option<f64> {
        (records.len() > 1).then(|| records.iter().map(|r| r.ln_bayes_against).sum())
    }

    /// The first record whose held-out part the candidate makes clearly worse
    /// (`RecordFold::contradicts`), when the records together are not clearly for it
    /// (ln B ADD_LN_BAYES, the bar of an added effect).
    ///
    /// Until session 49 any record clearly worse refused the candidate. That made a joint
    /// analysis the records' intersection, and it named less than the better record
    /// alone: the peer's steps + chirp (seed 1, form error) refused a hidden manifold
    /// volume that the steps alone name, for the chirp's even pieces (ln B 30.8 against,
    /// where the steps' second half gave ln B 102.0 for; the other fold 223.6 for and 0.0
    /// against). A record that contradicts the others because the bench changed between
    /// them is still refused: the sensor-delay test in `tests`
    /// (`an_effect_one_record_alone_demands_is_refused`) measures the plain record at ln
    /// B 1215 against and the delayed one at 252 for. A contradiction the others outweigh
    /// is reported (`Fold::outweighed`).
    ///
    /// A record the model before explains within its noise on that part (held-out gap
    /// at most NOISE_FLOOR_GAP) is never outweighed: its residual is the noise, so its
    /// factor is a clean measurement, and a candidate that spoils a record already
    /// explained is bending into the others' form error. The Rust bench's joint steps +
    /// chirp (seed 2, form error, viscous friction hidden: 175 N s/m against the known
    /// 400) proposed the manifold volume; the steps' halves took it by ln B 344 and 289,
    /// the chirp's pieces, at 0.95 and 0.92 of their noise, refused it by 150 and 40.
    /// Outweighed, the run added the volume at 0.40 of the thesis's and then the oil mass,
    /// two effects the bench does not have (session 49, measured); the peer's chirp that
    /// refused the hidden volume was at 3.42 of its noise.
    pub fn contradiction(&self) -> Option<&RecordFold> {
        let outweighed = self.ln_bayes_against.is_some_and(|t| t <= -ADD_LN_BAYES);
        self.records
            .iter()
            .find(|r| r.contradicts() && (!outweighed || r.explained()))
    }

    /// The first record clearly worse where it was held out that the records together
    /// outweigh: the records disagree, and the report says so.
    pub fn outweighed(&self) -> Option<&RecordFold> {
        if self.contradiction().is_some() {
            return None;
        }
        self.records.iter().find(|r| r.contradicts())
    }
}

/// One record's held-out part in a fold of several records: its gap under the model
/// before the step and with the candidate, and the ln Bayes factor of the model before
/// over the candidate there (`evidence::score` with no price, in the model before's
/// independent samples); and the gap of the same record's fitted part under each, the
/// fits' own misfit on it.
#[derive(Debug, Clone, Serialize)]
pub struct RecordFold {
    pub record: String,
    pub gap_before: f64,
    pub gap_after: f64,
    pub ln_bayes_against: f64,
    pub fitted_gap_before: f64,
    pub fitted_gap_after: f64,
}

impl RecordFold {
    /// The candidate makes this record's held-out part clearly worse (ln B
    /// CLEAR_LN_BAYES for the model before): an effect one record demands and another
    /// refuses is no property of the bench (a sensor swapped between two recordings).
    ///
    /// How the record's fitted part fared is reported beside it (`fitted_gap_before`,
    /// `fitted_gap_after`) but does not waive the refusal. Session 48 measured such a
    /// waiver (refuse only when the fitted part is no better either) on the peer's steps +
    /// chirp (seed 1, form error, 12 cases) and the Rust bench's (seed 2, 6 cases). The
    /// manifold volume it was written for is worse on both parts of the chirp (held-out
    /// even pieces 3.42 -> 4.33, ln B 30.8 against; fitted odd pieces 4.24 -> 4.34), a
    /// contradiction either way, and stayed refused. It waived two record folds: the
    /// losses on that record (held out 3.42 -> 4.07, ln B 22.7 against) for a fitted part
    /// 1 % better (4.24 -> 4.19), refused for another reason anyway; and the volume in
    /// the volume + oil mass + losses case's end question (chirp odd pieces, ln B 61.8
    /// against), which then let the run stand with the volume first where, refused, it
    /// had continued to the oil mass (both hidden). A candidate that fits the part of a
    /// record it saw and mispredicts the rest of it is the overfitting the held-out check
    /// is for.
    fn contradicts(&self) -> bool {
        self.ln_bayes_against >= CLEAR_LN_BAYES
    }

    /// The model before the step explains this held-out part within its noise.
    fn explained(&self) -> bool {
        self.gap_before <= NOISE_FLOOR_GAP
    }
}

/// The held-out verdict on one candidate.
#[derive(Debug, Clone, Serialize)]
pub struct Validation {
    pub effect: String,
    pub folds: Vec<Fold>,
    /// For a delay of every sensor: what each signal it took further from the data says
    /// alone (`common_delay`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sensors: Vec<SensorSay>,
    /// For a candidate that brings effects it requires (the losses bring the passages'
    /// volume and oil mass at built-in size): each of those effects' own candidate, held
    /// out on the same folds (`Judge::validate`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub parts: Vec<Part>,
}

/// The held-out gap, fold by fold, of a candidate of one effect that a candidate of
/// several brings, and the ln Bayes factor of the candidate of several over it on the
/// held-out parts together (`evidence::score` with no price, counted in the
/// several's held-out residual's independent samples).
#[derive(Debug, Clone, Serialize)]
pub struct Part {
    pub effect: String,
    pub gaps: Vec<f64>,
    pub ln_bayes: f64,
}

/// One fold's held-out part under a fitted model: its gap, chi-square and independent
/// samples (`evidence::effective_samples`), and with several records each record's.
struct HeldOut {
    gap: f64,
    chi2: f64,
    effective: f64,
    records: Vec<HeldOut>,
}

impl HeldOut {
    /// `p` on `left_out`; a failed simulation is infinitely far.
    fn of(left_out: &Target, p: &Params) -> Self {
        let Some(r) = left_out.residuals(p) else {
            let failed = || HeldOut {
                gap: f64::INFINITY,
                chi2: f64::INFINITY,
                effective: 1.0,
                records: Vec::new(),
            };
            return HeldOut {
                records: left_out.records.iter().map(|_| failed()).collect(),
                ..failed()
            };
        };
        let misfit = |r: &[f64], blocks: &[usize]| {
            let chi2 = chi2(r);
            HeldOut {
                gap: (chi2 / r.len().max(1) as f64).sqrt(),
                chi2,
                effective: evidence::effective_samples(r, blocks).0,
                records: Vec::new(),
            }
        };
        let mut whole = misfit(r.as_slice(), &left_out.blocks());
        if let Some(parts) = left_out.parts(r.as_slice()).filter(|p| p.len() > 1) {
            whole.records = parts
                .into_iter()
                .map(|(record, part)| misfit(part, &record.blocks()))
                .collect();
        }
        whole
    }
}

/// A fold under a fitted model: its held-out part, and the gap of each record's fitted
/// part (with several records, reported beside its held-out part: `RecordFold`).
struct Misfits {
    held_out: HeldOut,
    fitted: Vec<f64>,
}

impl Misfits {
    fn of(f: &Split, p: &Params) -> Self {
        let fitted = if f.records.is_empty() {
            Vec::new()
        } else {
            let whole = HeldOut::of(&f.fitted, p);
            whole.records.iter().map(|r| r.gap).collect()
        };
        Misfits {
            held_out: HeldOut::of(&f.held_out, p),
            fitted,
        }
    }
}

impl Validation {
    /// Every held-out part is closer to the data than under the model before the step,
    /// and than under each effect it brings fitted alone; every signal a delay of all
    /// sensors took further from the data sees some delay.
    pub fn passed(&self) -> bool {
        !self.folds.is_empty()
            && self.folds.iter().all(|f| f.gap_after < f.gap_before)
            && self.sensors.iter().all(SensorSay::sees)
            && self.unbeaten().is_none()
            && self.contradicted().is_none()
    }

    /// The first record whose held-out part the candidate makes clearly worse, in a fold
    /// whose records together do not outweigh it (`Fold::contradiction`).
    fn contradicted(&self) -> Option<(&Fold, &RecordFold)> {
        self.folds
            .iter()
            .find_map(|f| f.contradiction().map(|r| (f, r)))
    }

    /// The records disagree: a record clearly worse where it was held out, outweighed by
    /// the fold's records together, as a sentence (None when no record is).
    pub fn disagreement(&self) -> Option<String> {
        let (f, r) = self
            .folds
            .iter()
            .find_map(|f| f.outweighed().map(|r| (f, r)))?;
        Some(format!(
            "The records disagree: the {} came out clearly worse (ln B {:.1} against it), \
             outweighed by the fold's held-out data together (ln B {:.1} for it)",
            r.record,
            r.ln_bayes_against,
            -f.ln_bayes_against.unwrap_or(0.0)
        ))
    }

    /// The first effect it brings that, fitted alone, it does not beat clearly on the
    /// held-out parts (ln B ADD_LN_BAYES, the bar of an added effect: what it adds beyond
    /// that effect is missing physics claimed too).
    fn unbeaten(&self) -> Option<&Part> {
        self.parts.iter().find(|p| p.ln_bayes < ADD_LN_BAYES)
    }

    /// The held-out check in words (report.md).
    pub fn describe(&self) -> String {
        let folds: Vec<String> = self
            .folds
            .iter()
            .map(|f| {
                format!(
                    "fitted without the {}, its gap went {:.2} -> {:.2}",
                    f.held_out, f.gap_before, f.gap_after
                )
            })
            .collect();
        let mut text = format!("Held out: {}. ", folds.join("; "));
        let records: Vec<String> = self
            .folds
            .iter()
            .flat_map(|f| &f.records)
            .map(|r| {
                format!(
                    "the {} {:.2} -> {:.2} (ln B {:.1} against it; the rest of that record, \
                     fitted on, {:.2} -> {:.2})",
                    r.record,
                    r.gap_before,
                    r.gap_after,
                    r.ln_bayes_against,
                    r.fitted_gap_before,
                    r.fitted_gap_after
                )
            })
            .collect();
        if !records.is_empty() {
            text.push_str(&format!("Record by record: {}. ", records.join("; ")));
        }
        if let Some(d) = self.disagreement() {
            text.push_str(&format!("{d}. "));
        }
        if !self.parts.is_empty() {
            let each: Vec<String> = self
                .parts
                .iter()
                .map(|p| {
                    let gaps: Vec<String> = p.gaps.iter().map(|g| format!("{g:.2}")).collect();
                    format!(
                        "`{}` {} (ln B {:.1} for it over that)",
                        p.effect,
                        gaps.join(", "),
                        p.ln_bayes
                    )
                })
                .collect();
            text.push_str(&format!(
                "Each effect it brings, fitted alone on the same folds: {}. ",
                each.join("; ")
            ));
        }
        if !self.sensors.is_empty() {
            let each: Vec<String> = self.sensors.iter().map(|s| s.describe()).collect();
            text.push_str(&format!(
                "A delay of every sensor, read on each signal it took further from the data: {}. ",
                each.join("; ")
            ));
            if !self.sensors.iter().all(|s| s.sees()) {
                text.push_str(
                    "The signals disagree on the delay: the mark of a lag of some sensors alone \
                     (the pressure transducers' own dynamics read as a delay on steps), which no \
                     candidate holds. Check those sensors' response. ",
                );
            }
        }
        text
    }

    /// Why it did not pass, in words.
    pub fn why_refused(&self) -> String {
        if !self.sensors.iter().all(SensorSay::sees) {
            return "a signal it took further from the data sees no delay alone".into();
        }
        if let Some((f, r)) = self.contradicted() {
            let together = f.ln_bayes_against.unwrap_or(r.ln_bayes_against);
            // the two ways `Fold::contradiction` refuses, named apart: a fold that is not
            // clearly for it, or a record the model before already explains
            let why = if together <= -ADD_LN_BAYES {
                format!(
                    "though the fold's held-out data together are for it (ln B {:.1}), the \
                     model before explains that record within its noise there (gap {:.2})",
                    -together, r.gap_before
                )
            } else {
                format!(
                    "which the fold's held-out data together do not outweigh (ln B {together:.1} \
                     against it)"
                )
            };
            return format!(
                "clearly worse on the {} it was not fitted on (ln B {:.1} against it; the \
                 rest of that record, fitted on, {:.2} -> {:.2}), {why}",
                r.record, r.ln_bayes_against, r.fitted_gap_before, r.fitted_gap_after,
            );
        }
        match self.unbeaten() {
            Some(p) if self.folds.iter().all(|f| f.gap_after < f.gap_before) => format!(
                "not clearly better on the data it was not fitted on than `{}` alone, which \
                 it brings (ln B {:.1})",
                p.effect, p.ln_bayes
            ),
            _ => "no better on the data it was not fitted on".into(),
        }
    }
}

/// The held-out check of one round: the records (`target`, called `names`), the model
/// before the step and the parameters carried with every fit. The model before the step
/// is judged on the folds once, on the first candidate checked (`baseline`).
pub struct Judge<'a> {
    target: &'a Target<'a>,
    names: &'a [String],
    model: &'a Params,
    carried: &'a [Fitted],
    progress: bool,
    before: OnceCell<Vec<Misfits>>,
}

impl<'a> Judge<'a> {
    pub fn new(
        target: &'a Target<'a>,
        names: &'a [String],
        model: &'a Params,
        carried: &'a [Fitted],
        progress: bool,
    ) -> Self {
        Judge {
            target,
            names,
            model,
            carried,
            progress,
            before: OnceCell::new(),
        }
    }

    /// The held-out gap of each fold under the model before the step, its carried
    /// parameters re-fitted on the fold's fitted part: both sides of the comparison then
    /// know the same data (against the model as fitted on everything, whose
    /// recalibrations had seen the held-out part, a manifold inertia hidden on steps with
    /// form error was refused, measured). The folds run in parallel.
    fn baseline(&self) -> &[Misfits] {
        self.before.get_or_init(|| {
            let parts = folds(self.target, self.names);
            let bar =
                crate::parallel::bar(parts.len(), "held out, the model before", self.progress);
            let refit = Candidate {
                kind: StepKind::Recalibrate,
                effect: None,
                fitted: self.carried.to_vec(),
                signature: "the model before the step",
                switches_on: &[],
            };
            crate::parallel::map(
                &parts,
                &bar,
                |f| f.name.clone(),
                |f| {
                    if self.carried.is_empty() {
                        Misfits::of(f, self.model)
                    } else {
                        Misfits::of(f, &fit(&f.fitted, self.model, &refit, &[]).params)
                    }
                },
            )
        })
    }

    /// Fit `whole`'s candidate on each fold's fitted part (with the carried parameters,
    /// as the step itself) and compare the held-out part's gap with the model before the
    /// step's (`baseline`), fold by fold; the folds run in parallel. A delay of every
    /// sensor is also read signal by signal from `whole`, its fit on all the data
    /// (`common_delay`).
    ///
    /// `parts` are the candidates of the effects `whole` brings beside its own (the
    /// passages' volume and oil mass the losses require). A candidate of several effects
    /// must also beat each of them alone on what neither saw: the simpler account is taken
    /// when the record cannot show what the rest adds. A hidden manifold volume on the
    /// peer's steps (seed 5, form error; truth 0.98 of the thesis's volume) was named as the
    /// losses, which brought the volume and oil mass at built-in size and fitted losses
    /// 0.75, gap 5.55 against the volume's 5.78 (ln B 17.9, on the data both were fitted
    /// on; the bench has neither oil mass nor losses), measured in session 43.
    pub fn validate(&self, whole: &Fit, parts: &[&Fit]) -> Validation {
        let c = &whole.candidate;
        let before = self.baseline();
        let after = self.held_out(c);
        let parts = parts
            .iter()
            .map(|p| {
                let alone = self.held_out(&p.candidate);
                let ln_bayes = after
                    .iter()
                    .zip(&alone)
                    .map(|(a, b)| (&a.held_out, &b.held_out))
                    .map(|(a, b)| match (a.chi2.is_finite(), b.chi2.is_finite()) {
                        // one failed simulation of the effect alone is no evidence for it
                        (true, false) => f64::INFINITY,
                        _ => evidence::score(b.chi2, a.chi2, a.effective, 0.0) / 2.0,
                    })
                    .sum();
                Part {
                    effect: p.candidate.name(),
                    gaps: alone.iter().map(|h| h.held_out.gap).collect(),
                    ln_bayes,
                }
            })
            .collect();
        Validation {
            effect: c.name(),
            folds: folds(self.target, self.names)
                .iter()
                .zip(&after)
                .zip(before)
                .map(|((f, a), b)| {
                    let records: Vec<RecordFold> = a
                        .held_out
                        .records
                        .iter()
                        .zip(&b.held_out.records)
                        .zip(&f.records)
                        .zip(&f.held_out_of)
                        .map(|(((ra, rb), record), &k)| RecordFold {
                            record: record.clone(),
                            gap_before: rb.gap,
                            gap_after: ra.gap,
                            ln_bayes_against: match (ra.chi2.is_finite(), rb.chi2.is_finite()) {
                                (false, true) => f64::INFINITY,
                                _ => evidence::score(ra.chi2, rb.chi2, rb.effective, 0.0) / 2.0,
                            },
                            fitted_gap_before: b.fitted[k],
                            fitted_gap_after: a.fitted[k],
                        })
                        .collect();
                    Fold {
                        held_out: f.name.clone(),
                        gap_before: b.held_out.gap,
                        gap_after: a.held_out.gap,
                        ln_bayes_against: Fold::together(&records),
                        records,
                    }
                })
                .collect(),
            sensors: common_delay::each_sensor(self.target, self.names, whole),
            parts,
        }
    }

    /// Each fold's held-out part, `c` fitted on the fold's fitted part with the carried
    /// parameters.
    fn held_out(&self, c: &Candidate) -> Vec<Misfits> {
        let parts = folds(self.target, self.names);
        let bar = crate::parallel::bar(
            parts.len(),
            &format!("held out, {}", c.name()),
            self.progress,
        );
        crate::parallel::map(
            &parts,
            &bar,
            |f| f.name.clone(),
            |f| Misfits::of(f, &fit(&f.fitted, self.model, c, self.carried).params),
        )
    }
}

#[cfg(test)]
mod tests;
