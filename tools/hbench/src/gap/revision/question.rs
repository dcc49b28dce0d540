//! Which steps of an ended run are asked again, and against what (`questions`).

use super::super::advice;
use super::super::effects::StepKind;
use super::super::search::Search;
use super::super::Step;
use super::stand_ins::{movers, stand_ins};
use super::{value, FAR_ABOVE_FLOOR_GAP};

/// An added effect whose own first parameter moved by more than this fraction between
/// its step and the run's end was taken on evidence the run's later steps took over, and
/// is asked again like a contested one (its rival must have paid its price). The
/// fraction is the 25 % within which issue 14 asks a named effect's size. A payload
/// hidden with form error (Rust steps, seed 3, a 0.25 ms LVDT lag) was taken for the
/// oil mass at step 1 (inertia scale 0.861, gap 1.97 against the payload's 2.13, ln B
/// 39); the run then re-fitted SV1's rated flow and null leakage, the viscous friction
/// and the moving mass, and ended at gap 1.07 with the oil mass at 0.525, 39 % down. Asked
/// again from the known model with the first three beside each, the payload won by ln B
/// 117 (gap 1.24 against 1.37, 2.93 kg against the truth's 2.35; measured, session 26).
pub const MOVED_BY: f64 = 0.25;

/// How far the step `s` of `run`, an added effect whose own first fitted parameter is
/// `own` (from its round, `question`'s `fitted`), saw that parameter move by the run's
/// end: (path, value at the step, value at the end), when the relative change exceeds
/// MOVED_BY.
fn moved(run: &Search, s: &Step, own: Option<&'static str>) -> Option<(&'static str, f64, f64)> {
    if s.kind != StepKind::Add {
        return None;
    }
    let path = own?;
    let at_step = s.parameters.get(path)?.as_f64()?;
    let at_end = hbmodel::params::param(path)?.get(&run.model);
    let change = (at_end / at_step - 1.0).abs();
    (change > MOVED_BY).then_some((path, at_step, at_end))
}

/// A step a run's end asks again (see `questions`).
pub(super) struct Question<'t> {
    /// Index of the step.
    pub(super) k: usize,
    /// The step's rival, or the best effects of its round when the rival was a
    /// recalibration the run made anyway (`stand_ins`).
    pub(super) rivals: Vec<String>,
    /// Why: contested, or taken clearly by a run far above the floor.
    pub(super) why: String,
    /// The search before the step.
    pub(super) earlier: Search<'t>,
    /// The parameters the run recalibrated after it.
    pub(super) later: Vec<&'static str>,
}

/// The steps of the ended run `run` worth asking again, earliest first: contested, an added
/// effect whose size the run's later steps moved by more than MOVED_BY (`moved`), or
/// (when the run ended above FAR_ABOVE_FLOOR_GAP) any step that added an effect; in the
/// last two its rival must have paid its price. Its choice and rival fit no parameter in
/// common, and the run recalibrated something after it.
///
/// A run far above the floor lacks something in its structure, so an effect it added
/// clearly may have been taken for what it lacks. A recalibration it took clearly is
/// not asked again, whether its rival was a recalibration (a question of values) or an
/// added effect. On the peer bench every run's first step re-fits SV2's flow over an
/// added effect or SV1's null bias. Session 34 asked the clear recalibrations whose
/// rival adds an effect: they were asked in 17 of the 24 peer step records of seeds 1
/// and 2 (SV2's flow at step 1, SV1's null leakage at step 2 or 3), and the run stood
/// every time (ln B 7.8-116 for the recalibration). In session 33 SV2's flow was the
/// question in 19 of those records (over SV1's null bias in 15, over an added effect
/// in 4), and they stood too. Not asking them, CI's peer sample (steps, seed 1: the
/// valve asymmetry, the volume, the sensor delay, nothing hidden) took 368 CPU s
/// against 469, side by side in one run, with the same answers (measured, session 35).
/// An added effect, asked, can fall. The payload hidden there (seed 1, 3.18 kg) was
/// taken for the manifold's volume at step 2 (gap 10.36; losses 10.75, payload 12.54,
/// oil mass 12.58), before the run re-fitted SV1's null leakage; asked again between the
/// volume, the losses and the payload with it, the payload won by ln B 158.8 at 3.05 kg
/// and the run continued to gap 4.60 against 5.82 (measured, session 34). The
/// runner-up alone (the losses) would not have asked it.
pub(super) fn questions<'t>(run: &Search<'t>) -> Vec<Question<'t>> {
    // the parameters a candidate of step k's round fitted
    let fitted = |k: usize, name: &str| -> Vec<&'static str> {
        run.rounds.get(k).map_or(Vec::new(), |r| {
            r.fits
                .iter()
                .filter(|(_, f)| f.name == name)
                .flat_map(|(_, f)| f.candidate.fitted.iter().map(|x| x.path))
                .collect()
        })
    };
    // a run that ends far above the noise floor left something no step explained: a
    // step taken clearly may have been taken without what the run learned after it
    let far = run.gap > FAR_ABOVE_FLOOR_GAP;
    run.steps.iter().enumerate().filter_map(|(k, s)| {
        let contested = advice::contested(s);
        let mine = fitted(k, &s.name);
        let shifted = moved(run, s, mine.first().copied());
        let rival = if shifted.is_some() {
            advice::rival(s)
        } else if far {
            advice::rival(s).filter(|_| contested.is_some() || s.kind == StepKind::Add)
        } else {
            contested
        }?;
        // a choice and a rival that fit a parameter in common are one physics within two
        // bounds (SV2's flow and null re-fitted, or `valve_asymmetry`): asked again they
        // stayed within ln B 0.2 on each of the 9 peer runs that had them first (steps,
        // seed 1, form error, measured), and the later question went unasked
        if fitted(k, rival).iter().any(|p| mine.contains(p)) {
            return None;
        }
        let earlier = run.before(k)?;
        let later: Vec<&'static str> = run
            .recalibrated
            .iter()
            .copied()
            .filter(|p| !earlier.recalibrated.contains(p))
            .collect();
        // when the step's own round had every recalibration the run made, asking it
        // again would repeat it
        if later.is_empty() {
            return None;
        }
        let theirs = fitted(k, rival);
        let rivals = if !theirs.is_empty() && theirs.iter().all(|p| later.contains(p)) {
            stand_ins(run, k, &mine, &later)
        } else if far {
            // the run ended far above the floor: the runner-up was the best rival without
            // the later recalibrations, and the round's other effects that paid their
            // price may be better with them (`stand_ins`, beside it)
            let mut all = vec![rival.to_string()];
            for e in stand_ins(run, k, &mine, &later) {
                if !all.contains(&e) {
                    all.push(e);
                }
            }
            all
        } else {
            vec![rival.to_string()]
        };
        if rivals.is_empty() {
            return None;
        }
        // an effect added later that moved the step's size may be what the step took
        // the place of: it is asked beside the rival (`movers`)
        let rivals = if shifted.is_some() {
            movers(run, k, &mine, rivals)
        } else {
            rivals
        };
        let why = if contested.is_some() {
            "contested".to_string()
        } else if let Some((path, at_step, at_end)) = shifted {
            format!(
                "taken clearly, but the run's later steps moved its `{path}` from {} to {}: they took over part of what it explained",
                value(at_step),
                value(at_end)
            )
        } else {
            format!(
                "taken clearly, but the run ended at gap {:.2}, far above the noise floor",
                run.gap
            )
        };
        Some(Question {
            k,
            rivals,
            why,
            earlier,
            later,
        })
    })
    .collect()
}

/// The earliest question of `questions`, if any.
#[cfg(test)]
pub(super) fn question<'t>(run: &Search<'t>) -> Option<Question<'t>> {
    questions(run).into_iter().next()
}
