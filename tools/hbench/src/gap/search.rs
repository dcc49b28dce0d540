//! The workflow's forward search: round after round, every candidate is fitted from the
//! model as it stands, and the best one worth adding that improves what it was not fitted
//! on becomes a step (`selection`). The search keeps what each round started from, so a
//! step can be taken back and the search continued from there (`revision`).

use hbmodel::Params;

use super::budget::{Clock, ROUND};
use super::effects::{Fitted, StepKind};
use super::fit::{self, Fit, Target};
use super::holdout::{self, Validation};
use super::{
    advice, evidence, json_values, misfit, recalibrate, selection, signals, Scored, Step,
    MAX_STEPS, MIN_IMPROVEMENT, NOISE_FLOOR_GAP,
};

/// How far each list had grown when a round started: what taking the search back to
/// that round keeps.
#[derive(Debug, Clone, Copy)]
struct Mark {
    carried: usize,
    recalibrated: usize,
    refusals: usize,
}

/// A search in progress or ended (`verdict` set).
#[derive(Clone)]
pub struct Search<'t> {
    target: &'t Target<'t>,
    names: &'t [String],
    within: f64,
    progress: bool,
    pub model: Params,
    pub gap: f64,
    pub steps: Vec<Step>,
    /// Every parameter fitted so far, re-adjusted by each later fit.
    pub carried: Vec<Fitted>,
    /// Each round's start, correlation time and fits, for the advice.
    pub rounds: Vec<advice::Round>,
    /// Effects that won a round but did not improve the data they were not fitted on.
    pub refusals: Vec<Validation>,
    /// Added effects the end question withdrew because, fitted again with the run's later
    /// recalibrations, they ended on a physical bound of their own
    /// (`revision::withdraw`): never proposed again in the run continued without them.
    pub withdrawn: Vec<String>,
    /// The known model's parameters recalibrated, for the advice's question.
    pub recalibrated: Vec<&'static str>,
    /// The last round's candidates when it added nothing: why the search stopped.
    pub rejected: Vec<Scored>,
    /// Independent samples the final residual is worth (N / tau).
    pub effective: f64,
    pub verdict: String,
    /// The search stops once this many effects are in (MAX_STEPS unless a user asks
    /// for fewer, `Settings::max_effects`).
    pub max_effects: usize,
    /// The run's clock and budget (`budget`): each round is timed, and none is started
    /// that the time left cannot hold.
    pub clock: Option<&'t Clock>,
    /// What the clock calls this search's rounds: [`ROUND`], each timed as a phase, or
    /// the end question's continued search's (`budget::CONTINUED`, `revision`), held to
    /// the budget but timed within the question's phase.
    pub phase: &'static str,
    marks: Vec<Mark>,
}

impl<'t> Search<'t> {
    /// A search from `start` on `target`, whose records are called `names`; the base
    /// model's parameters are recalibrated within +-`within`.
    pub fn new(
        target: &'t Target<'t>,
        names: &'t [String],
        start: &Params,
        within: f64,
        progress: bool,
    ) -> Self {
        Search {
            target,
            names,
            within,
            progress,
            model: start.clone(),
            gap: target.gap(start),
            steps: Vec::new(),
            carried: Vec::new(),
            rounds: Vec::new(),
            refusals: Vec::new(),
            withdrawn: Vec::new(),
            recalibrated: Vec::new(),
            rejected: Vec::new(),
            effective: target.len() as f64,
            verdict: String::new(),
            max_effects: MAX_STEPS,
            clock: None,
            phase: ROUND,
            marks: Vec::new(),
        }
    }

    /// The records searched, as one fitting target, and their names.
    pub fn target(&self) -> (&'t Target<'t>, &'t [String]) {
        (self.target, self.names)
    }

    /// Added effects (recalibrations not counted).
    pub fn added(&self) -> usize {
        self.steps
            .iter()
            .filter(|s| s.kind == StepKind::Add)
            .count()
    }

    /// Rounds until no candidate is worth adding, `max_effects` effects are in, or the
    /// next round would not fit the time budget (`budget`).
    pub fn run(&mut self) {
        self.verdict = loop {
            if self.added() >= self.max_effects {
                break format!(
                    "stopped after {} effects with the gap at {:.2}",
                    self.max_effects, self.gap
                );
            }
            let name = format!("{} {}", self.phase, self.rounds.len() + 1);
            // the longest round so far is what the next one is expected to cost; the
            // first always runs
            let expected = match self.clock.map(|c| c.admit(&name, c.longest_round())) {
                Some(Err(expected)) => break format!(
                    "stopped by the time budget before {name} (expected {expected:.1} s) with the gap at {:.2}: the search was not finished",
                    self.gap
                ),
                Some(Ok(expected)) => expected,
                None => None,
            };
            let verdict = match self.clock.filter(|_| self.phase == ROUND) {
                Some(clock) => clock.time(&name, expected, || self.round()),
                None => self.round(),
            };
            if let Some(verdict) = verdict {
                break verdict;
            }
        };
    }

    /// One round: a step taken (None), or the verdict of a search that ends.
    fn round(&mut self) -> Option<String> {
        let (target, gap) = (self.target, self.gap);
        self.mark();
        let done: Vec<&str> = self.carried.iter().map(|f| f.path).collect();
        let open = recalibrate::candidates(&self.model, self.within, &done);
        let absent = self
            .rounds
            .last()
            .and_then(|r| r.fits.iter().map(|(_, f)| f).find(|f| f.absent()));
        let fits = selection::fit_all(
            target,
            &self.model,
            gap,
            &self.carried,
            open,
            absent,
            self.progress,
        );
        // what the residual left by the model so far is worth, record by record: a
        // missing effect leaves a coloured residual, whose samples are not independent
        let (misfit, tau) = misfit(target, &self.model, gap);
        let effective = misfit.effective();
        let before = signals::Baseline::of(target, self.names, &self.model);
        let scored: Vec<(Scored, &Fit)> = fits
            .iter()
            .map(|f| (Scored::of(f, &misfit, &before), f))
            .collect();
        let round = advice::Round {
            start: self.model.clone(),
            tau,
            fits: scored
                .iter()
                .map(|(s, f)| (s.score, (*f).clone()))
                .collect(),
        };
        let eligible: Vec<&(Scored, &Fit)> = scored
            .iter()
            .filter(|(s, f)| {
                s.worth_adding(gap)
                    && !self.refusals.iter().any(|v| v.effect == f.name)
                    && !self.withdrawn.contains(&f.name)
            })
            .collect();
        let judge = holdout::Judge::new(
            target,
            self.names,
            &self.model,
            &self.carried,
            self.progress,
        );
        let best = selection::select(eligible, &before, &judge, &mut self.refusals);
        let Some(((_, winner), validated)) = best else {
            self.rounds.push(round);
            self.rejected = scored.iter().map(|(s, _)| s.clone()).collect();
            self.effective = effective;
            return Some(self.stopped());
        };
        let mut step = step_of(
            winner,
            &self.model,
            gap,
            scored.iter().map(|(s, _)| s.clone()).collect(),
            effective,
            validated,
        );
        step.spread = fit::spread(target, winner, tau);
        self.take(step, round, winner);
        None
    }

    /// Note how far each list has grown as a round starts.
    fn mark(&mut self) {
        self.marks.push(Mark {
            carried: self.carried.len(),
            recalibrated: self.recalibrated.len(),
            refusals: self.refusals.len(),
        });
    }

    /// Why a search that added nothing in its last round ended.
    fn stopped(&self) -> String {
        let gap = self.gap;
        if gap <= NOISE_FLOOR_GAP {
            return format!("the model explains the data within their noise (gap {gap:.2}, noise floor 1); no effect adds more than its complexity price");
        }
        format!(
            "no candidate lowers the gap ({gap:.2}) by more than {:.0} % and its complexity price (an added effect, clearly: by ln B {:.0} over the model without it){}",
            MIN_IMPROVEMENT * 100.0,
            evidence::ADD_LN_BAYES,
            if self.refusals.is_empty() {
                String::new()
            } else {
                let effects: Vec<String> = self
                    .refusals
                    .iter()
                    .map(|v| format!("{}, {}", v.effect, v.why_refused()))
                    .collect();
                format!(
                    " and passes the held-out check (refused: {})",
                    effects.join("; ")
                )
            }
        )
    }

    /// Take `step`, the fit `winner` of `round`: the model becomes the fit's, its
    /// parameters are carried into every later fit (brought-along effects stay at their
    /// built-in sizes: re-fitting them too made each later fit 4-parametric with the slow
    /// passage dynamics, 480 CPU s for one record, measured), a recalibrated parameter
    /// within its recalibration bounds. The step's gap is split by signal here, where
    /// every step passes (a round's, and a revision's), from the model before it.
    pub fn take(&mut self, mut step: Step, round: advice::Round, winner: &Fit) {
        if self.marks.len() == self.rounds.len() {
            // a step taken without a round of this search's own (`revision`)
            self.mark();
        }
        step.signals = signals::per_signal(self.target, self.names, &self.model, &winner.params);
        self.rounds.push(round);
        self.gap = winner.gap;
        self.model = winner.params.clone();
        for f in &winner.candidate.fitted {
            // a parameter carried already (an earlier effect's, re-fitted with the
            // others before a step was re-asked) is the earlier step's
            if self.carried.iter().any(|c| c.path == f.path) {
                continue;
            }
            self.carried.push(*f);
            if winner.candidate.kind == StepKind::Recalibrate {
                self.recalibrated.push(f.path);
            }
        }
        self.steps.push(step);
    }

    /// The search as it stood before step `k` was taken; None if there was no step `k`.
    pub fn before(&self, k: usize) -> Option<Search<'t>> {
        let mark = *self.marks.get(k)?;
        let mut s = self.clone();
        s.model = self.rounds.get(k)?.start.clone();
        s.gap = self.steps.get(k)?.gap_before;
        s.steps.truncate(k);
        s.rounds.truncate(k);
        s.marks.truncate(k);
        s.carried.truncate(mark.carried);
        s.recalibrated.truncate(mark.recalibrated);
        s.refusals.truncate(mark.refusals);
        s.rejected.clear();
        s.effective = self.target.len() as f64;
        s.verdict.clear();
        Some(s)
    }
}

/// The step `winner` makes from `model` at gap `gap`, among the round's `candidates`.
pub fn step_of(
    winner: &Fit,
    model: &Params,
    gap: f64,
    candidates: Vec<Scored>,
    effective: f64,
    validation: Option<Validation>,
) -> Step {
    let brings: Vec<hbmodel::Effect> = match (winner.candidate.kind, winner.candidate.effect) {
        (StepKind::Add, Some(e)) => e
            .spec()
            .requires
            .iter()
            .copied()
            .filter(|r| !model.has(*r))
            .collect(),
        _ => Vec::new(),
    };
    let preference = evidence::preference(&Scored::contenders(&candidates));
    Step {
        kind: winner.candidate.kind,
        effect: winner.candidate.effect.map(|e| e.name().to_string()),
        name: winner.name.clone(),
        brings: brings.iter().map(|e| e.name().to_string()).collect(),
        parameters: json_values(&winner.values),
        gap_before: gap,
        gap_after: winner.gap,
        candidates,
        effective_samples: effective,
        validation,
        preference,
        spread: Vec::new(),
        signals: Vec::new(),
    }
}
