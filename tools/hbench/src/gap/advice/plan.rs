//! What the advice does after a run, planned before it is costed (issue 14 items 6
//! and 7): the question it asks of the designs, or the search for what records explained
//! within their noise cannot show (`unseen`). The budget costs what the plan will
//! simulate (`budget::advice_wall`), so the estimate is the advice's own count, not an
//! upper bound read down by a share.

use hbmodel::Params;

use super::super::budget::{advice_wall, Clock};
use super::super::experiments::{design_of, designs, Design};
use super::super::fit::Target;
use super::super::{Record, Step, NOISE_FLOOR_GAP};
use super::recorded::{self, observed};
use super::refit::Refit;
use super::{assess, earliest_contested, leading, needed, recommend, unseen, Advice, Round, Scale};

/// The question the advice asks after a run, when `needed`: the model its leading
/// models are re-fitted from, the leading models, and what the record showed of them.
/// The earliest contested step is asked first: what it chose shaped every later step,
/// and the last round no longer holds the rival (a payload taken for the manifold's oil
/// mass at the first step, Rust bench with form error, steps: the last round's question
/// was which of the later small effects to add, and its advised moves named nothing,
/// measured). Its two fits, from the model before that step, are the leading models.
/// Without a contested step, the model as it stands and the last round's best.
pub struct Question<'r> {
    pub from: Params,
    pub leading: Vec<(String, Params)>,
    pub scale: Scale,
    /// The round whose fits the records read the pairs at, and the step that round
    /// took if it is the model as it stands (`recorded::observed`).
    round: &'r Round,
    accepted: Option<&'r str>,
    /// The contested step asked about, if any.
    step: Option<usize>,
}

impl<'r> Question<'r> {
    /// The question after a run that ended at `model` and `gap`; None when not `needed`.
    pub fn of(model: &Params, steps: &'r [Step], gap: f64, rounds: &'r [Round]) -> Option<Self> {
        if !needed(steps, gap) {
            return None;
        }
        if let Some(u) = earliest_contested(steps, rounds) {
            return Some(Question {
                scale: Scale::new(u.tau, u.gap),
                from: u.from,
                leading: u.pair.into(),
                round: &rounds[u.step],
                accepted: None,
                step: Some(u.step),
            });
        }
        let last = rounds.last()?;
        // a run cut by the limit took a step in its last round: that winner is the model
        // as it stands (a run that ended on its own rejected every candidate of a last
        // round)
        let accepted = steps
            .last()
            .filter(|_| rounds.len() == steps.len())
            .map(|s| s.name.as_str());
        Some(Question {
            leading: leading(model, &last.fits, accepted),
            scale: Scale::new(last.tau, gap),
            from: model.clone(),
            round: last,
            accepted,
            step: None,
        })
    }

    /// The models simulated under every design to answer it (`assess`): the leading
    /// models and the steps of the refit that reads them, counted by the model whose
    /// cost each has (`Refit::costed`).
    pub fn models(&self) -> Vec<(Params, usize)> {
        Refit::new(&self.from, &self.leading).costed(&self.from, &self.leading)
    }
}

/// What the advice does after a run: ask a question of the designs, search what records
/// explained within their noise cannot show (`unseen`), or nothing (the run stopped above
/// the noise floor with no round to read).
pub enum Plan<'r> {
    // boxed: a question holds its models, the other plans nothing
    Ask(Box<Question<'r>>),
    Unseen,
    Nothing,
}

impl<'r> Plan<'r> {
    /// The plan after a run that ended at `model` and `gap` with its `steps` and
    /// `rounds`: as `run` will carry it out, read before it starts so that the budget
    /// costs what it will simulate.
    pub fn of(model: &Params, steps: &'r [Step], gap: f64, rounds: &'r [Round]) -> Self {
        match Question::of(model, steps, gap, rounds) {
            Some(q) => Plan::Ask(Box::new(q)),
            None if gap > NOISE_FLOOR_GAP => Plan::Nothing,
            None => Plan::Unseen,
        }
    }
}

/// The advice on a question: every design assessed, read at what the records showed of
/// those they were made under (`recorded`, `experiments::design_of`), and recommended.
pub fn after(
    q: &Question,
    noise: &[(&'static str, f64)],
    recorded: &[Design],
    progress: bool,
) -> Advice {
    let designs = designs();
    let mut assessed = assess(&q.from, &q.leading, noise, q.scale, &designs, progress);
    recorded::read_at_records(&mut assessed, recorded, |a, b| {
        observed(&q.round.fits, q.accepted, a, b)
    });
    let mut a = recommend(&q.from, &q.leading, q.scale, assessed);
    if let Some(step) = q.step {
        a.question = format!(
            "step {} could not tell `{}` from `{}`",
            step + 1,
            q.leading[0].0,
            q.leading[1].0
        );
    }
    a
}

/// What to measure next after a run that ended at `model` and `gap`, as `plan` says: the
/// question its steps and rounds left, or, explained within the noise, what the records
/// could not have shown; a new record is read at the noise the first record shows. Each
/// part runs only if the clock's time left holds what it will simulate: the blind
/// spots' search under the records, then the designs under the spots it found.
pub fn run(
    clock: &Clock,
    model: &Params,
    plan: &Plan,
    (rounds, gap): (&[Round], f64),
    (target, records): (&Target, &[Record]),
    progress: bool,
) -> Option<Advice> {
    let noise = &target.records[0].noise;
    // what the advice simulates, costed before it starts (`advice_wall`)
    let cost =
        |records, designs: &[(Params, usize)]| advice_wall(clock, target, model, records, designs);
    match plan {
        Plan::Ask(q) => {
            let recorded: Vec<Design> = records
                .iter()
                .filter_map(|r| design_of(&r.experiment, &r.measured))
                .collect();
            clock.within("advice", cost(0, &q.models()), || {
                after(q, noise, &recorded, progress)
            })
        }
        Plan::Unseen => {
            let tau = rounds.last().map_or(1.0, |r| r.tau);
            let searched = cost(unseen::searched(model), &[]);
            let spots = clock.within("advice: blind spots", searched, || {
                unseen::blind_spots(model, target, tau)
            })?;
            if spots.is_empty() {
                return None;
            }
            let shown = cost(0, &unseen::models(model, &spots));
            let scale = Scale::new(tau, gap);
            clock
                .within("advice", shown, || {
                    unseen::check(model, spots, noise, scale, progress)
                })
                .flatten()
        }
        Plan::Nothing => None,
    }
}

#[cfg(test)]
mod tests {
    use hbmodel::effects::Effect;
    use hbmodel::Params;

    use super::super::super::blind::known_model;
    use super::super::tests::{round, step};
    use super::super::AS_IS;
    use super::*;

    /// What the budget costs before the advice starts is what the advice then does
    /// (`Plan`): a contested step is asked about, from the model before it; a run above the
    /// noise floor asks its last round; a run within it searches its blind spots; a run with
    /// no round to read asks nothing. Under the designs the unseen search simulates the model,
    /// each blind spot and the refit that reads them: one more spot costs the spot and a step
    /// of each of its own parameters, each costed as the spot (`Refit::costed`).
    #[test]
    fn the_advice_is_planned_before_it_is_costed() {
        let first = [("inertia", 40.0), ("payload", 38.0), ("volume", 10.0)];
        let clear = [("inertia", 40.0), ("payload", -1.0)];
        let model = Params::default();
        let (steps, rounds) = ([step("inertia", &first)], [round(&first)]);
        let Plan::Ask(q) = Plan::of(&model, &steps, 1.0, &rounds) else {
            panic!("a contested step is a question");
        };
        let names: Vec<&str> = q.leading.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!((q.step, names), (Some(0), vec!["inertia", "payload"]));
        let count = |m: &[(Params, usize)]| m.iter().map(|(_, n)| n).sum::<usize>();
        let refit = Refit::new(&q.from, &q.leading).models.len();
        assert_eq!(count(&q.models()), 2 + refit);
        let (steps, rounds) = ([step("inertia", &clear)], [round(&clear)]);
        assert!(matches!(
            Plan::of(&model, &steps, 1.0, &rounds),
            Plan::Unseen
        ));
        let Plan::Ask(q) = Plan::of(&model, &steps, 2.0, &rounds) else {
            panic!("a run above the noise floor asks its last round");
        };
        assert_eq!((q.step, q.leading[0].0.as_str()), (None, AS_IS));
        assert!(matches!(Plan::of(&model, &[], 2.0, &[]), Plan::Nothing));

        let known = known_model(&[]);
        let none = count(&unseen::models(&known, &[]));
        let mut air = known.clone();
        air.effects.set(Effect::EntrainedAir, true);
        let spot = [("entrained_air".to_string(), air, 0.5)];
        let own = crate::gap::effects::all()
            .into_iter()
            .find(|c| c.name() == "entrained_air")
            .expect("a candidate")
            .fitted
            .len();
        // the air and the steps of its own parameters are costed as the air; the rest as
        // the model
        let models = unseen::models(&known, &spot);
        assert_eq!(count(&models), none + 1 + own);
        let costed_as_air = models.iter().find(|(p, _)| p.has(Effect::EntrainedAir));
        assert_eq!(costed_as_air.map(|(_, n)| *n), Some(1 + own));
        assert!(unseen::searched(&known) > Refit::new(&known, &[]).models.len());
    }
}
