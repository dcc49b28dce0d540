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
//! steps record's first and last steps), or, when its drive sweeps in frequency, every
//! other one of its PIECES pieces (`interleaved`). The whole record is always simulated:
//! the held-out part's states come from the model running through the fitted part.

use std::cell::OnceCell;

use hbmodel::Params;
use serde::Serialize;

use super::common_delay::{self, SensorSay};
use super::data::{Drive, Experiment, Measured};
use super::effects::{Candidate, Fitted, StepKind};
use super::evidence::{self, ADD_LN_BAYES};
use super::fit::{fit, span, Fit, Target};

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

/// One fold's held-out part under a fitted candidate: its gap, chi-square and
/// independent samples (`evidence::effective_samples`).
struct HeldOut {
    gap: f64,
    chi2: f64,
    effective: f64,
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
fn interleaved(window: std::ops::Range<usize>) -> [Vec<std::ops::Range<usize>>; 2] {
    let (start, n) = (window.start, window.len());
    let piece = |k: usize| start + k * n / PIECES..start + (k + 1) * n / PIECES;
    let pick = |parity: usize| (0..PIECES).filter(|k| k % 2 == parity).map(piece).collect();
    [pick(0), pick(1)]
}

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
    let [whole] = &r.window[..] else {
        return Vec::new();
    };
    let (start, end) = (whole.start, whole.end);
    let middle = start + (end - start) / 2;
    if middle - start < MIN_HALF {
        return Vec::new();
    }
    let half = |w: Vec<std::ops::Range<usize>>| Target {
        records: vec![r.part(w)],
    };
    if sweeps_in_frequency(r.experiment, r.measured) {
        let [odd, even] = interleaved(whole.clone());
        return vec![
            ("even pieces".into(), half(odd.clone()), half(even.clone())),
            ("odd pieces".into(), half(even), half(odd)),
        ];
    }
    vec![
        (
            "second half".into(),
            half(span(start..middle)),
            half(span(middle..end)),
        ),
        (
            "first half".into(),
            half(span(middle..end)),
            half(span(start..middle)),
        ),
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
                    .map(|(a, b)| match (a.chi2.is_finite(), b.chi2.is_finite()) {
                        // one failed simulation of the effect alone is no evidence for it
                        (true, false) => f64::INFINITY,
                        _ => evidence::score(b.chi2, a.chi2, a.effective, 0.0) / 2.0,
                    })
                    .sum();
                Part {
                    effect: p.candidate.name(),
                    gaps: alone.iter().map(|h| h.gap).collect(),
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
                .map(|(((held_out, _, _), a), &gap_before)| Fold {
                    held_out: held_out.clone(),
                    gap_before,
                    gap_after: a.gap,
                })
                .collect(),
            sensors: common_delay::each_sensor(self.target, self.names, whole),
            parts,
        }
    }

    /// Each fold's held-out part, `c` fitted on the fold's fitted part with the carried
    /// parameters.
    fn held_out(&self, c: &Candidate) -> Vec<HeldOut> {
        let parts = folds(self.target, self.names);
        let bar = crate::parallel::bar(
            parts.len(),
            &format!("held out, {}", c.name()),
            self.progress,
        );
        crate::parallel::map(
            &parts,
            &bar,
            |(held_out, _, _)| held_out.clone(),
            |(_, fitted, left_out)| {
                let p = fit(fitted, self.model, c, self.carried).params;
                match left_out.residuals(&p) {
                    Some(r) => HeldOut {
                        gap: (r.norm_squared() / r.len().max(1) as f64).sqrt(),
                        chi2: r.norm_squared(),
                        effective: evidence::effective_samples(r.as_slice(), &left_out.blocks()).0,
                    },
                    None => HeldOut {
                        gap: f64::INFINITY,
                        chi2: f64::INFINITY,
                        effective: 1.0,
                    },
                }
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use std::ops::Range;

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

    /// Each fold's name, the samples it fits and the samples it holds out.
    type Windows = Vec<(String, Vec<Range<usize>>, Vec<Range<usize>>)>;

    /// The folds of one record of `kind` (seed 1, no form error), and its length.
    fn windows_of(kind: Kind) -> (usize, Windows) {
        let s = Setup::new(Simulator::Rust, false, &[], 1);
        let (e, m) = record(&s, kind, 1);
        let one = Target {
            records: vec![Record::new(&m, &e, noise_levels(&m))],
        };
        let windows = folds(&one, &[kind.name().to_string()])
            .iter()
            .map(|(name, fitted, left)| {
                let w = |t: &Target| t.records[0].window.clone();
                (name.clone(), w(fitted), w(left))
            })
            .collect();
        (m.time.len(), windows)
    }

    /// One record is held out by halves that tile it (the steps, the moves, whose halves
    /// are alike); several records one at a time.
    #[test]
    fn folds_leave_out_each_part_once() {
        for kind in [Kind::Steps, Kind::Moves] {
            let (n, windows) = windows_of(kind);
            let halves = [
                (span(0..n / 2), span(n / 2..n)),
                (span(n / 2..n), span(0..n / 2)),
            ];
            let names = ["second half", "first half"];
            for (k, (name, fitted, left)) in windows.into_iter().enumerate() {
                assert_eq!(
                    (name.as_str(), (fitted, left)),
                    (names[k], halves[k].clone())
                );
            }
        }
        let s = Setup::new(Simulator::Rust, false, &[], 1);
        let (e, m) = record(&s, Kind::Steps, 1);
        let n = m.time.len();
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

    /// A record whose drive sweeps in frequency (the chirp) is held out by every other
    /// piece of PIECES, each fold spanning the sweep.
    #[test]
    fn a_sweeping_record_is_held_out_by_interleaved_pieces() {
        let (n, windows) = windows_of(Kind::Chirp);
        assert_eq!(windows.len(), 2);
        for (name, fitted, left) in &windows {
            assert_eq!(
                (fitted.len(), left.len()),
                (PIECES / 2, PIECES / 2),
                "{name}"
            );
            // the two tile the record, pieces alternating from its start to its end
            let mut all: Vec<_> = fitted.iter().chain(left).cloned().collect();
            all.sort_by_key(|w| w.start);
            assert_eq!(all.first().map(|w| w.start), Some(0));
            assert_eq!(all.last().map(|w| w.end), Some(n));
            assert!(all.windows(2).all(|w| w[0].end == w[1].start), "{all:?}");
            let starts = |ws: &[Range<usize>]| ws.iter().map(|w| w.start).collect::<Vec<_>>();
            assert!(
                starts(fitted).iter().all(|a| !starts(left).contains(a)),
                "{name}: a piece is both fitted and held out"
            );
        }
        assert_eq!(windows[0].0, "even pieces");
        assert_eq!(
            windows[1].2[0],
            0..n / PIECES,
            "the odd ones start the record"
        );
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
        let v = Judge::new(&target, &names, known, &[], false).validate(&joint, &[]);
        assert!(!v.passed(), "{v:?}");
        let plain = &v.folds[1];
        assert!(
            plain.gap_after > plain.gap_before,
            "fitted on the delayed record, the delay must worsen the other: {v:?}"
        );
    }

    /// A candidate of several effects that improves both held-out halves is refused when
    /// one of the effects it brings, fitted alone, does as well there within ln B 3 (the
    /// peer's seed-5 volume against the losses: 1.4, measured), and taken when it beats
    /// every one of them clearly.
    #[test]
    fn several_effects_at_once_must_beat_each_they_bring_on_held_out_data() {
        let fold = |held_out: &str, gap_after: f64| Fold {
            held_out: held_out.into(),
            gap_before: 20.0,
            gap_after,
        };
        let part = |effect: &str, ln_bayes: f64| Part {
            effect: effect.into(),
            gaps: vec![10.1, 10.1],
            ln_bayes,
        };
        let losses = |parts| Validation {
            effect: "manifold_losses".into(),
            folds: vec![fold("second half", 10.0), fold("first half", 10.0)],
            sensors: Vec::new(),
            parts,
        };
        let close = losses(vec![
            part("manifold_inertia", 40.0),
            part("manifold_volume", 1.4),
        ]);
        assert!(!close.passed());
        assert!(
            close.why_refused().contains("`manifold_volume` alone"),
            "{}",
            close.why_refused()
        );
        let clear = losses(vec![
            part("manifold_inertia", 40.0),
            part("manifold_volume", 3.5),
        ]);
        assert!(clear.passed());
        // against the model before the step, the old check, still comes first
        let worse = Validation {
            folds: vec![fold("second half", 21.0), fold("first half", 10.0)],
            ..clear
        };
        assert!(!worse.passed());
        assert_eq!(
            worse.why_refused(),
            "no better on the data it was not fitted on"
        );
    }
}
