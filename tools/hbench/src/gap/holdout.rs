//! Held-out validation (issue 14 item 2): an effect is added only if, fitted without part
//! of the data, it improves that part.
//!
//! The scores (`evidence::score`) judge a candidate on the data it was fitted on. Under
//! model-form error an effect can lower that misfit by bending itself into the shape of
//! physics the model lacks, and the information criterion, whatever its sample count,
//! cannot tell such a fit from a true one. A fit that learned the record's particulars
//! instead of the bench's physics does not carry over to data it did not see. The folds:
//! with several records, each record is left out in turn and the others are fitted (a
//! sweep fitted predicts the steps); with one record, its first and second halves (a
//! sweep's low and high frequencies; a steps record's first and last steps). The whole
//! record is always simulated: the held-out half's states come from the model running
//! through the fitted half.

use std::cell::OnceCell;

use hbmodel::Params;
use serde::Serialize;

use super::effects::{Candidate, Fitted, StepKind};
use super::fit::{fit, Target};

/// One fold: the gap of `held_out` under the model before the step and with the
/// candidate, each fitted on the rest of the data.
#[derive(Debug, Clone, Serialize)]
pub struct Fold {
    pub held_out: String,
    pub gap_before: f64,
    pub gap_after: f64,
}

/// The held-out verdict on one candidate.
#[derive(Debug, Clone, Serialize)]
pub struct Validation {
    pub effect: String,
    pub folds: Vec<Fold>,
}

impl Validation {
    /// Every held-out part is closer to the data than under the model before the step.
    pub fn passed(&self) -> bool {
        !self.folds.is_empty() && self.folds.iter().all(|f| f.gap_after < f.gap_before)
    }
}

/// Least samples a half-record holds for it to be held out: a shorter half shows too
/// little of the loop's response (one 0.1 s step response at 1 kHz) to judge a fit by.
const MIN_HALF: usize = 100;

/// The (name, fitted part, held-out part) of each fold of `target`, whose records are
/// called `names`.
pub fn folds<'a>(
    target: &'a Target<'a>,
    names: &[String],
) -> Vec<(String, Target<'a>, Target<'a>)> {
    let records = &target.records;
    if records.len() > 1 {
        return (0..records.len())
            .map(|k| {
                let pick = |keep: &dyn Fn(usize) -> bool| Target {
                    records: records
                        .iter()
                        .enumerate()
                        .filter(|(j, _)| keep(*j))
                        .map(|(_, r)| r.part(r.window.clone()))
                        .collect(),
                };
                let name = names
                    .get(k)
                    .map_or_else(|| format!("record {}", k + 1), |n| format!("record `{n}`"));
                (name, pick(&|j| j != k), pick(&|j| j == k))
            })
            .collect();
    }
    let Some(r) = records.first() else {
        return Vec::new();
    };
    let (start, end) = (r.window.start, r.window.end);
    let middle = start + (end - start) / 2;
    if middle - start < MIN_HALF {
        return Vec::new();
    }
    let half = |w: std::ops::Range<usize>| Target {
        records: vec![r.part(w)],
    };
    vec![
        ("second half".into(), half(start..middle), half(middle..end)),
        ("first half".into(), half(middle..end), half(start..middle)),
    ]
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
    before: OnceCell<Vec<f64>>,
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
    pub fn baseline(&self) -> &[f64] {
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
                |(held_out, _, _)| held_out.clone(),
                |(_, fitted, left_out)| {
                    if self.carried.is_empty() {
                        left_out.gap(self.model)
                    } else {
                        left_out.gap(&fit(fitted, self.model, &refit, &[]).params)
                    }
                },
            )
        })
    }

    /// Fit `c` on each fold's fitted part (with the carried parameters, as the step
    /// itself) and compare the held-out part's gap with the model before the step's
    /// (`baseline`), fold by fold. The folds run in parallel.
    pub fn validate(&self, c: &Candidate) -> Validation {
        let before = self.baseline();
        let parts = folds(self.target, self.names);
        let bar = crate::parallel::bar(
            parts.len(),
            &format!("held out, {}", c.name()),
            self.progress,
        );
        let after = crate::parallel::map(
            &parts,
            &bar,
            |(held_out, _, _)| held_out.clone(),
            |(_, fitted, left_out)| left_out.gap(&fit(fitted, self.model, c, self.carried).params),
        );
        Validation {
            effect: c.name(),
            folds: parts
                .iter()
                .zip(after)
                .zip(before)
                .map(|(((held_out, _, _), gap_after), &gap_before)| Fold {
                    held_out: held_out.clone(),
                    gap_before,
                    gap_after,
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use hbmodel::effects::Effect;
    use hbmodel::sensors::SensorParams;

    use super::*;
    use crate::gap::blind::Setup;
    use crate::gap::data::{Experiment, Measured};
    use crate::gap::effects::candidate;
    use crate::gap::fit::Record;
    use crate::gap::hide::{measure_truth, Kind};
    use crate::gap::noise_levels;
    use crate::gap::variants::Simulator;

    fn record(s: &Setup, kind: Kind, seed: u64) -> (Experiment, Measured) {
        let sp = SensorParams {
            seed,
            ..SensorParams::default()
        };
        measure_truth(&s.bench, kind, &sp).expect("the bench runs")
    }

    /// One record is held out by halves that tile it; several records one at a time.
    #[test]
    fn folds_leave_out_each_part_once() {
        let s = Setup::new(Simulator::Rust, false, &[], 1);
        let (e, m) = record(&s, Kind::Steps, 1);
        let n = m.time.len();
        let one = Target {
            records: vec![Record::new(&m, &e, noise_levels(&m))],
        };
        let halves = folds(&one, &["steps".into()]);
        let windows: Vec<_> = halves
            .iter()
            .map(|(_, fitted, left)| {
                (
                    fitted.records[0].window.clone(),
                    left.records[0].window.clone(),
                )
            })
            .collect();
        assert_eq!(windows, vec![(0..n / 2, n / 2..n), (n / 2..n, 0..n / 2)]);
        let two = Target {
            records: vec![
                Record::new(&m, &e, noise_levels(&m)),
                Record::new(&m, &e, noise_levels(&m)),
            ],
        };
        let names = ["a".to_string(), "b".to_string()];
        for (k, (name, fitted, left)) in folds(&two, &names).iter().enumerate() {
            assert_eq!(name, &format!("record `{}`", names[k]));
            assert_eq!((fitted.records.len(), left.records.len()), (1, 1));
            assert_eq!(left.len(), n * 3);
        }
    }

    /// An effect one record demands and the other refuses is no property of the bench:
    /// one steps record made with a sensor delay (the position transducer swapped for a
    /// slower one between two recordings), the other without. A delay lowers the joint gap
    /// of the two; the held-out check refuses it: fitted on the delayed record, the delay
    /// makes the other worse.
    #[test]
    fn an_effect_one_record_alone_demands_is_refused() {
        let delayed = Setup::new(Simulator::Rust, false, &[Effect::SensorDelay], 2);
        let plain = Setup::new(Simulator::Rust, false, &[], 2);
        let (e1, m1) = record(&delayed, Kind::Steps, 2);
        let (e2, m2) = record(&plain, Kind::Steps, 3);
        let target = Target {
            records: vec![
                Record::new(&m1, &e1, noise_levels(&m1)),
                Record::new(&m2, &e2, noise_levels(&m2)),
            ],
        };
        let delay = candidate(Effect::SensorDelay).expect("a candidate");
        let known = &plain.known;
        let joint = fit(&target, known, &delay, &[]);
        let before = target.gap(known);
        assert!(
            joint.gap < 0.9 * before,
            "in-sample, the delay must look worth adding: gap {before} -> {}",
            joint.gap
        );
        let names = ["delayed".to_string(), "plain".to_string()];
        let v = Judge::new(&target, &names, known, &[], false).validate(&delay);
        assert!(!v.passed(), "{v:?}");
        let plain = &v.folds[1];
        assert!(
            plain.gap_after > plain.gap_before,
            "fitted on the delayed record, the delay must worsen the other: {v:?}"
        );
    }
}
