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
//! out clearly worse (`folds`, `Validation::contradicted`). The whole record is always
//! simulated: the held-out part's states come from the model running through the fitted
//! part.

use std::cell::OnceCell;
use std::ops::Range;

use hbmodel::Params;
use serde::Serialize;

use super::common_delay::{self, SensorSay};
use super::data::{Drive, Experiment, Measured};
use super::effects::{Candidate, Fitted, StepKind};
use super::evidence::{self, ADD_LN_BAYES, CLEAR_LN_BAYES};
use super::fit::{fit, span, Fit, Record, Target};

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
            let chi2: f64 = r.iter().map(|x| x * x).sum();
            HeldOut {
                gap: (chi2 / r.len().max(1) as f64).sqrt(),
                chi2,
                effective: evidence::effective_samples(r, blocks).0,
                records: Vec::new(),
            }
        };
        let mut whole = misfit(r.as_slice(), &left_out.blocks());
        if left_out.records.len() > 1 {
            // the residual holds the records one after the other (`Target::residuals`)
            let mut at = 0;
            whole.records = left_out
                .records
                .iter()
                .map(|record| {
                    let n = record.len();
                    let blocks = vec![record.samples(); record.noise.len()];
                    at += n;
                    misfit(&r.as_slice()[at - n..at], &blocks)
                })
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

    /// The first record whose held-out part the candidate makes clearly worse
    /// (`RecordFold::contradicts`).
    fn contradicted(&self) -> Option<&RecordFold> {
        self.folds
            .iter()
            .flat_map(|f| &f.records)
            .find(|r| r.contradicts())
    }

    /// The first effect it brings that, fitted alone, it does not beat clearly on the
    /// held-out parts (ln B ADD_LN_BAYES, the bar of an added effect: what it adds beyond
    /// that effect is missing physics claimed too).
    fn unbeaten(&self) -> Option<&Part> {
        self.parts.iter().find(|p| p.ln_bayes < ADD_LN_BAYES)
    }

    /// Why it did not pass, in words.
    pub fn why_refused(&self) -> String {
        if !self.sensors.iter().all(SensorSay::sees) {
            return "a signal it took further from the data sees no delay alone".into();
        }
        if let Some(r) = self.contradicted() {
            return format!(
                "clearly worse on the {} it was not fitted on (ln B {:.1} against it; the \
                 rest of that record, fitted on, {:.2} -> {:.2})",
                r.record, r.ln_bayes_against, r.fitted_gap_before, r.fitted_gap_after
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

/// Least samples a half-record holds for it to be held out: a shorter half shows too
/// little of the loop's response (one 0.1 s step response at 1 kHz) to judge a fit by.
const MIN_HALF: usize = 100;

/// Pieces a frequency-sweeping record is cut into for its interleaved folds: each fold
/// holds sixteen of them, 62.5 ms of a 2 s chirp each, spread over the whole sweep. The
/// top piece is in one fold only, so the other fold's fit must reach it from the piece
/// below: on the 2-200 Hz log chirp a piece spans a factor 100^(1/PIECES) in frequency.
/// With 16 pieces (a factor 1.33, session 36) the peer's manifold oil mass (chirp,
/// seed 1, form error), told from its rivals by ln B 29.8, was refused: fitted on the
/// even pieces, which end at 150 Hz, it made the odd ones, which hold 150-200 Hz, worse
/// (5.05 -> 5.16) while the other fold improved (5.00 -> 3.33). With 32 (a factor 1.15)
/// both folds improve (4.10 -> 3.86, 4.44 -> 2.84) and it is named, 1.32 against 1.44
/// (measured, session 37; docs/gap.md has what else the change moved).
const PIECES: usize = 32;

/// How many times more often the drive crosses its mean in one half of a record than in
/// the other for the halves to hold different frequency bands. Measured on `hide`'s
/// records: a 2 s chirp crosses 15 times in its first half and 156 in its second, a 2.5 s
/// closed-loop sweep 14 and 247; +-10 mm steps and the moves once in each.
const OTHER_BAND: f64 = 3.0;

/// Whether the record's drive (its reference in closed loop, SV1's command in open loop)
/// sweeps in frequency, so that its halves are different bands. Then a time half is no
/// fair test: an effect whose signature lies above the first half's frequencies (a valve
/// lag on a chirp, Rust bench, seed 2, form error: it won its round, gap 1.72 against the
/// delay's 1.74) cannot be fitted on that half and is refused for what the half could not
/// show (second half 3.21 -> 3.28), not for what it got wrong.
fn sweeps_in_frequency(experiment: &Experiment, measured: &Measured) -> bool {
    let column = match &experiment.drive {
        Drive::Proportional { reference, .. } => reference.as_str(),
        Drive::OpenLoop => "u1",
    };
    let Some(x) = measured.get(column) else {
        return false;
    };
    let n = x.len().max(1) as f64;
    let mean = x.iter().sum::<f64>() / n;
    let sd = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    // a tenth of the standard deviation of hysteresis: the converter's noise on a
    // recorded command does not count as crossings
    let middle = x.len() / 2;
    let (a, b) = (
        crossings(&x[..middle], mean, 0.1 * sd),
        crossings(&x[middle..], mean, 0.1 * sd),
    );
    // one more than the count on each side: a half without a crossing is a low band too
    let (a, b) = ((a + 1) as f64, (b + 1) as f64);
    a.max(b) >= OTHER_BAND * a.min(b)
}

/// Times `part` crosses `mean`, a side counting once it is left by more than `h`.
fn crossings(part: &[f64], mean: f64, h: f64) -> usize {
    let mut side = 0i8;
    let mut count = 0;
    for x in part {
        let now = if x - mean > h {
            1
        } else if x - mean < -h {
            -1
        } else {
            continue;
        };
        count += usize::from(side != 0 && now != side);
        side = now;
    }
    count
}

/// The odd (first, third, ...) and the even pieces of `window` cut into PIECES: each
/// fold spans the whole sweep.
fn interleaved(window: Range<usize>) -> [Vec<Range<usize>>; 2] {
    let (start, n) = (window.start, window.len());
    let piece = |k: usize| start + k * n / PIECES..start + (k + 1) * n / PIECES;
    let pick = |parity: usize| (0..PIECES).filter(|k| k % 2 == parity).map(piece).collect();
    [pick(0), pick(1)]
}

/// One record's own fold: its name, the windows fitted and the windows held out.
type OwnFold = (&'static str, Vec<Range<usize>>, Vec<Range<usize>>);

/// A record's two folds: its halves, or, when its drive sweeps in frequency, its
/// interleaved pieces; None when a half would be shorter than MIN_HALF.
fn own_folds(r: &Record) -> Option<[OwnFold; 2]> {
    let [whole] = &r.window[..] else {
        return None;
    };
    let (start, end) = (whole.start, whole.end);
    let middle = start + (end - start) / 2;
    if middle - start < MIN_HALF {
        return None;
    }
    if sweeps_in_frequency(r.experiment, r.measured) {
        let [odd, even] = interleaved(whole.clone());
        return Some([
            ("even pieces", odd.clone(), even.clone()),
            ("odd pieces", even, odd),
        ]);
    }
    Some([
        ("second half", span(start..middle), span(middle..end)),
        ("first half", span(middle..end), span(start..middle)),
    ])
}

/// One fold of the data: the part fitted and the part held out.
pub struct Split<'a> {
    pub name: String,
    pub fitted: Target<'a>,
    pub held_out: Target<'a>,
    /// With several records, the name of each record's held-out part, in `held_out`'s
    /// order.
    pub records: Vec<String>,
    /// Which of `fitted`'s records each of `held_out`'s is (a record too short to halve
    /// is fitted in every fold and held out in none).
    pub held_out_of: Vec<usize>,
}

/// Each fold of `target`, whose records are called `names`.
///
/// Several records are held out together, each by its own folds: fold j fits part j's
/// complement of every record jointly and holds out part j of each. Before session 45 a
/// record was left out whole and predicted from the others, which asks every record to
/// show the effect alone, the opposite of what a joint analysis is for. On the peer's
/// steps + chirp (seed 1, form error) it named 2 of 7 cases worse than the better record
/// alone and none better: a dry friction the steps name and the chirp cannot fit (it
/// ran to its 500 N bound there) was refused, fitted on the chirp, for making the steps
/// worse. A record that contradicts the others is still caught: `Validation::passed`
/// refuses an effect that makes any record's held-out part clearly worse.
pub fn folds<'a>(target: &'a Target<'a>, names: &[String]) -> Vec<Split<'a>> {
    let records = &target.records;
    let own: Vec<Option<[OwnFold; 2]>> = records.iter().map(own_folds).collect();
    if own.iter().all(Option::is_none) {
        return Vec::new();
    }
    (0..2)
        .map(|j| {
            // a record too short to halve is fitted in every fold and held out in none
            let fitted = Target {
                records: records
                    .iter()
                    .zip(&own)
                    .map(|(r, o)| {
                        r.part(
                            o.as_ref()
                                .map_or_else(|| r.window.clone(), |o| o[j].1.clone()),
                        )
                    })
                    .collect(),
            };
            let held_out = Target {
                records: records
                    .iter()
                    .zip(&own)
                    .filter_map(|(r, o)| o.as_ref().map(|o| r.part(o[j].2.clone())))
                    .collect(),
            };
            // the names of the records held out, each with its part of this fold
            let records: Vec<String> = own
                .iter()
                .enumerate()
                .filter_map(|(k, o)| {
                    let name = names
                        .get(k)
                        .map_or_else(|| format!("record {}", k + 1), |n| format!("`{n}`"));
                    o.as_ref().map(|o| format!("{} of {name}", o[j].0))
                })
                .collect();
            let held_out_of = (0..own.len()).filter(|&k| own[k].is_some()).collect();
            match &own[..] {
                [Some(o)] => Split {
                    name: o[j].0.to_string(),
                    fitted,
                    held_out,
                    records: Vec::new(),
                    held_out_of,
                },
                _ => Split {
                    name: records.join(", "),
                    fitted,
                    held_out,
                    records,
                    held_out_of,
                },
            }
        })
        .collect()
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
                .map(|((f, a), b)| Fold {
                    held_out: f.name.clone(),
                    gap_before: b.held_out.gap,
                    gap_after: a.held_out.gap,
                    records: a
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
                        .collect(),
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
