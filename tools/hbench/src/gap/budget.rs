//! Where an analysis spends its time, and a bounded-cost mode (issue 14, item 7: a 2 s
//! record analysed in 60 s on two cores).
//!
//! Every run keeps a clock of its phases: the search's rounds, the end question
//! (`revision`), the experiment advice and the records' description. Given a budget
//! (`hbench gap --budget`), a phase is started only if the time left holds what a phase of
//! its kind is expected to cost, read from what the run has measured so far; what was left
//! out is said in the report, so an answer cut short never passes for a finished one. The
//! first round always runs: without it there is no answer at all.
//!
//! The budget is in wall seconds, the time a user waits (the report gives CPU seconds
//! beside it). A phase is never interrupted once started: a fit stopped half-way would
//! give a score that looks valid and is not. So a run can overrun its budget by what its
//! last phase cost beyond the estimate; the report shows by how much.

use std::sync::Mutex;
use std::time::Instant;

use serde::Serialize;

use crate::bench::cpu::{process_seconds, thread_seconds};

/// The clock's name of the first simulation of the records (the starting model's gap),
/// timed for the report (the advice's estimate reads its models' costs, `advice_wall`).
pub const FIRST: &str = "first simulation";
/// The clock's name of the search's rounds ("round 2").
pub const ROUND: &str = "round";
/// The clock's name of an end question's continued search's rounds, held to the budget
/// but timed within the question's phase.
pub const CONTINUED: &str = "end question's round";

/// How much more than the run's measure a phase may cost: the largest ratio of a
/// round's wall time to the longest round before it, rounded up. Measured on the four
/// item-7 records (the Rust chirp, seed 1, form error, with nothing, the dry friction,
/// the manifold volume and the valve lag hidden), 12 runs: 0.47 to 2.04, the largest
/// the second round of the record with nothing hidden (18.3 s after 9.0 s; its fits
/// carry the first step's parameter beside their own). A later round fits more carried
/// parameters, and an added valve lag makes every simulation stiffer.
pub const MARGIN: f64 = 2.1;

/// Wall seconds a part of the experiment advice is expected to take (`advice::run`),
/// before the margin: `under_records` models simulated under the records (the search for
/// blind spots, `advice::unseen`) and the models `under_designs` simulated under every
/// design, each counted by the model whose cost it has (`advice::refit::Refit::costed`),
/// as the advice's plan lists them (`advice::Plan`).
///
/// Each part is costed in CPU seconds on its own kind of drive (`record_rate`,
/// `design_rate`), and turned into
/// wall seconds by how many wall seconds each CPU second of the run's rounds took
/// (`Clock::wall_per_cpu`): the rounds fit in parallel as the advice simulates in
/// parallel, on a machine as busy. Under the records every model is costed at `model`'s
/// rate, the model the advice starts from (which effects a search would switch on cost
/// what they cost only once simulated: on the item-7 records the search took 1.0-5.8 times
/// its estimate before the margin, 0.7-1.2 s, session 60). Under the designs each model is costed at
/// `model`'s design rate times how much its own simulations of the records cost against
/// `model`'s: one more simulation of the records per leading model, where the advice runs
/// 17.1 s of designs under each.
///
/// History: before session 59 it read the wall time of the run's first simulation of the
/// start model (one 14 ms sample, which a busy machine moved 1.9 times between two runs of
/// the same record); until session 60 it counted three leading models and both of the
/// advice's searches at `model`'s rate, times a share 0.6 calibrated on four records: on a
/// run stopped after the manifold's volume, whose question held the passages' losses, the
/// advice took 3.1-3.4 times that estimate with the margin (session 60).
pub fn advice_wall(
    clock: &Clock,
    target: &super::fit::Target,
    model: &hbmodel::Params,
    under_records: usize,
    under_designs: &[(hbmodel::Params, usize)],
) -> f64 {
    if under_records == 0 && under_designs.is_empty() {
        return 0.0;
    }
    let recorded: f64 = target.records.iter().map(|r| r.measured.duration()).sum();
    let designed: f64 = super::experiments::designs()
        .iter()
        .map(|d| d.duration)
        .sum();
    let record = record_rate(target, model);
    // the designs are timed only for a part that simulates them (the blind-spot search
    // does not)
    let design = if under_designs.is_empty() {
        0.0
    } else {
        design_rate(model)
    };
    let designs: f64 = under_designs
        .iter()
        .map(|(p, n)| {
            let own = record_rate(target, p);
            let relative = if own > 0.0 && record > 0.0 {
                own / record
            } else {
                1.0
            };
            design * relative * *n as f64
        })
        .sum();
    let cpu = designs * designed + record * recorded * under_records as f64;
    cpu * clock.wall_per_cpu()
}

/// `model`'s CPU seconds per simulated second on one core under the records: its
/// simulations of them, read from when they ran (`drive::simulation_cost`; run again if
/// no longer kept, a few milliseconds each); 0 where it cannot be simulated. Measured on
/// the four item-7 records (session 59): 0.0053-0.0066 on the chirp record without a
/// valve lag, 0.0324 with one.
fn record_rate(target: &super::fit::Target, model: &hbmodel::Params) -> f64 {
    per_second(
        target
            .records
            .iter()
            .map(|r| {
                let cost = super::drive::simulation_cost(model, r.experiment, r.measured);
                (cost, r.measured.duration())
            })
            .collect(),
    )
}

/// `model`'s CPU seconds per simulated second on one core under the advice's designs,
/// which are not the records' (a user's record may be any drive): one run under each
/// kind's standard design, timed here, 6.15 of the designs' 17.1 simulated seconds once,
/// where the advice simulates them all under each of its models (measured: 2 % of the
/// advice's CPU time); 0 where it cannot be simulated. Measured on the four item-7
/// records (session 59): 0.0072-0.0080 without a valve lag, 0.0328 with one.
fn design_rate(model: &hbmodel::Params) -> f64 {
    per_second(
        super::experiments::Kind::ALL
            .iter()
            .map(|&kind| {
                let d = super::experiments::Design::standard(kind);
                let cpu = thread_seconds();
                let ran = super::advice::simulate(model, &d).is_ok();
                (ran.then(|| thread_seconds() - cpu), d.duration)
            })
            .collect(),
    )
}

/// CPU seconds per simulated second of the runs (CPU seconds, None if it failed;
/// simulated seconds) that ran; 0 if none did.
fn per_second(runs: Vec<(Option<f64>, f64)>) -> f64 {
    let (cpu, simulated) = runs
        .into_iter()
        .filter_map(|(cpu, s)| Some((cpu?, s)))
        .fold((0.0, 0.0), |(c, t), (cpu, s)| (c + cpu, t + s));
    if simulated > 0.0 {
        cpu / simulated
    } else {
        0.0
    }
}

/// One phase of a run, timed.
#[derive(Debug, Clone, Serialize)]
pub struct Phase {
    /// "round 1", "end question", "advice: blind spots" (the search for what records
    /// explained within their noise cannot show, `advice::unseen`), "advice", "records".
    pub name: String,
    pub wall_s: f64,
    /// CPU seconds of every thread.
    pub cpu_s: f64,
    /// The wall seconds the clock expected before the phase started (`Clock::admit`),
    /// kept to show how well the budget reads the run.
    pub expected_s: Option<f64>,
}

/// What a run's clock tells the report.
#[derive(Debug, Clone, Serialize)]
pub struct Timing {
    /// The wall seconds the user allowed (`--budget`), if any.
    pub budget_s: Option<f64>,
    pub phases: Vec<Phase>,
    /// What the budget left out, in words ("round 3: expected 21 s, 12 s left").
    pub skipped: Vec<String>,
    pub wall_s: f64,
    pub cpu_s: f64,
}

/// A run's clock: the phases timed so far and the budget they are held to.
pub struct Clock {
    start: Instant,
    cpu0: f64,
    budget: Option<f64>,
    phases: Mutex<Vec<Phase>>,
    skipped: Mutex<Vec<String>>,
}

impl Clock {
    /// A clock started now, holding the run to `budget` wall seconds if given.
    pub fn new(budget: Option<f64>) -> Clock {
        Clock {
            start: Instant::now(),
            cpu0: process_seconds(),
            budget,
            phases: Mutex::new(Vec::new()),
            skipped: Mutex::new(Vec::new()),
        }
    }

    /// Wall seconds since the clock started.
    pub fn elapsed(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Run `work` as the phase `name`, timed beside what was `expected` of it (`admit`).
    pub fn time<T>(&self, name: &str, expected: Option<f64>, work: impl FnOnce() -> T) -> T {
        let (wall, cpu) = (Instant::now(), process_seconds());
        let out = work();
        let phase = Phase {
            name: name.to_string(),
            wall_s: wall.elapsed().as_secs_f64(),
            cpu_s: process_seconds() - cpu,
            expected_s: expected,
        };
        lock(&self.phases).push(phase);
        out
    }

    /// Run `work` as the phase `name` if the time left holds `measure` (`admit`); None
    /// when it was left out.
    pub fn within<T>(&self, name: &str, measure: f64, work: impl FnOnce() -> T) -> Option<T> {
        let expected = self.admit(name, Some(measure)).ok()?;
        Some(self.time(name, expected, work))
    }

    /// The longest wall time of the search's rounds so far, if any ran: what the next
    /// round, or an end question (which fits its candidates as a round does), is expected
    /// to cost. The longest, not the last: a later round fits more carried parameters.
    pub fn longest_round(&self) -> Option<f64> {
        lock(&self.phases)
            .iter()
            .filter(|p| p.name.starts_with(ROUND))
            .map(|p| p.wall_s)
            .max_by(f64::total_cmp)
    }

    /// Wall seconds per CPU second of the run's rounds so far: below 1 where they ran in
    /// parallel on a quiet machine, above where other work took the cores. 1 before any
    /// round ran (one core, nothing beside).
    pub fn wall_per_cpu(&self) -> f64 {
        let (wall, cpu) = lock(&self.phases)
            .iter()
            .filter(|p| p.name.starts_with(ROUND))
            .fold((0.0, 0.0), |(w, c), p| (w + p.wall_s, c + p.cpu_s));
        if wall > 0.0 && cpu > 0.0 {
            wall / cpu
        } else {
            1.0
        }
    }

    /// Whether the phase `what`, which the run measured at `measure` wall seconds (the
    /// longest round, the advice's estimate), fits the time left with the [`MARGIN`]:
    /// Ok with what is expected of it (None: nothing measured yet, it runs), or Err with
    /// the expectation the time left cannot hold, `what` then noted as left out.
    pub fn admit(&self, what: &str, measure: Option<f64>) -> Result<Option<f64>, f64> {
        let Some(expected) = measure.map(|m| m * MARGIN) else {
            return Ok(None);
        };
        let Some(budget) = self.budget else {
            return Ok(Some(expected));
        };
        let left = budget - self.elapsed();
        if expected <= left {
            return Ok(Some(expected));
        }
        lock(&self.skipped).push(format!(
            "{what}: expected {expected:.1} s, {:.1} s of the {budget:.0} s budget left",
            left.max(0.0)
        ));
        Err(expected)
    }

    /// The phases so far and what was left out.
    pub fn timing(&self) -> Timing {
        Timing {
            budget_s: self.budget,
            phases: lock(&self.phases).clone(),
            skipped: lock(&self.skipped).clone(),
            wall_s: self.elapsed(),
            cpu_s: process_seconds() - self.cpu0,
        }
    }
}

/// A poisoned lock still holds the list as the panicking thread left it, which is all a
/// clock needs.
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// `--budget` as a number of wall seconds a run can be held to.
pub fn check(budget: Option<f64>) -> Result<(), String> {
    match budget {
        Some(b) if !(b.is_finite() && b > 0.0) => Err(format!(
            "--budget {b}: a positive number of seconds is expected"
        )),
        _ => Ok(()),
    }
}

/// The report's words on the clock: each phase, and what the budget left out.
pub fn markdown(t: &Timing) -> String {
    let mut s = String::from(
        "## Time\n\n| phase | wall s | expected wall s | CPU s |\n|---|---|---|---|\n",
    );
    for p in &t.phases {
        let expected = p.expected_s.map_or("-".into(), |e| format!("{e:.2}"));
        s += &format!(
            "| {} | {:.2} | {expected} | {:.2} |\n",
            p.name, p.wall_s, p.cpu_s
        );
    }
    s += &format!(
        "| **whole analysis** | {:.1} | | {:.1} |\n\n",
        t.wall_s, t.cpu_s
    );
    match t.budget_s {
        None => s += "No time budget was set (`--budget`): every phase ran.\n",
        Some(b) if t.skipped.is_empty() => {
            s += &format!("Budget {b:.0} s: every phase fitted in it.\n")
        }
        Some(b) => {
            s += &format!(
                "Budget {b:.0} s. **Left out to hold it** (the answer above is the run as it stood, not a finished one):\n\n"
            );
            for w in &t.skipped {
                s += &format!("- {w}\n");
            }
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gap::blind::Setup;
    use crate::gap::hide::Kind;
    use crate::gap::variants::Simulator;
    use crate::gap::{run_with, Settings};
    use hbmodel::effects::Effect;

    /// A budget spent by the first round: the run keeps that round's step, starts no
    /// other round, no end question and no advice, and says so in its verdict and its
    /// timing (the record: +-10 mm steps with a 0.3 ms sensor delay hidden, which round 1
    /// names).
    #[test]
    fn a_spent_budget_ends_the_run_after_its_first_round_and_says_so() {
        let s = Setup::new(Simulator::Rust, false, &[Effect::SensorDelay], 2);
        let record = crate::gap::tests::record(&s, Kind::Steps, 2);
        let settings = Settings {
            budget: Some(1e-3),
            ..Settings::default()
        };
        let o = run_with(&s.known, std::slice::from_ref(&record), settings).expect("it runs");
        assert_eq!(o.steps.len(), 1, "{:?}", o.steps);
        assert_eq!(o.steps[0].name, "sensor_delay");
        assert!(o.verdict.contains("time budget"), "{}", o.verdict);
        let t = &o.timing;
        let rounds: Vec<&str> = t
            .phases
            .iter()
            .map(|p| p.name.as_str())
            .filter(|n| n.contains("round") || n.contains("question") || n.starts_with("advice"))
            .collect();
        assert_eq!(rounds, ["round 1"], "{:?}", t.phases);
        assert!(
            t.skipped.iter().any(|w| w.starts_with("round 2")),
            "{:?}",
            t.skipped
        );
        assert!(
            t.skipped.iter().any(|w| w.starts_with("advice")),
            "{:?}",
            t.skipped
        );
        assert!(markdown(t).contains("Left out to hold it"));
    }

    #[test]
    fn a_phase_runs_only_if_the_time_left_holds_it() {
        let free = Clock::new(None);
        assert_eq!(free.admit("round 2", Some(1e9)), Ok(Some(1e9 * MARGIN)));
        let held = Clock::new(Some(0.2));
        assert_eq!(held.admit("round 1", held.longest_round()), Ok(None));
        held.time("round 1", None, || {
            std::thread::sleep(std::time::Duration::from_millis(120))
        });
        let round = held.longest_round().expect("a round was timed");
        assert!(round >= 0.12, "round 1 took {round} s");
        // 0.08 s left: a second round like the first does not fit, a short phase does
        assert_eq!(held.admit("round 2", Some(round)), Err(round * MARGIN));
        assert!(held.admit("records", Some(0.01)).is_ok());
        let t = held.timing();
        assert_eq!(t.skipped.len(), 1);
        // the round's measure with the margin
        let expected = format!("round 2: expected {:.1} s", round * MARGIN);
        assert!(t.skipped[0].starts_with(&expected), "{}", t.skipped[0]);
        assert_eq!(t.phases[0].name, "round 1");
        assert!(markdown(&t).contains("Left out to hold it"));
        assert!(check(Some(0.0)).is_err() && check(Some(f64::NAN)).is_err());
        assert!(check(Some(60.0)).is_ok() && check(None).is_ok());
    }

    /// The advice is costed on the models it simulates, at the pace the run's rounds kept:
    /// a valve lag the run added, or one a question's model holds, makes every simulation
    /// of it stiffer, and a machine where a round's CPU second took several wall seconds
    /// makes every phase longer.
    #[test]
    fn the_advice_is_costed_on_the_models_it_simulates_at_the_runs_pace() {
        let s = Setup::new(Simulator::Rust, true, &[], 1);
        let records = [crate::gap::tests::record(&s, Kind::Chirp, 1)];
        let target = crate::gap::target_of(&records).expect("a target");
        let mut lagged = s.known.clone();
        lagged.effects.set(Effect::ValveDynamics, true);
        let quiet = Clock::new(None);
        assert_eq!(quiet.wall_per_cpu(), 1.0, "no round ran: one core");
        let plain = advice_wall(&quiet, &target, &s.known, 3, &[(s.known.clone(), 20)]);
        let stiff = advice_wall(&quiet, &target, &lagged, 3, &[(lagged.clone(), 20)]);
        assert!(plain > 0.0 && plain.is_finite(), "{plain}");
        assert!(
            stiff > 1.2 * plain,
            "with the lag {stiff} s, without {plain} s"
        );
        // a round whose CPU second took five wall seconds (its CPU time counts every
        // thread of the process, so a test beside would blur a timed one)
        let busy = Clock::new(None);
        lock(&busy.phases).push(Phase {
            name: "round 1".into(),
            wall_s: 5.0,
            cpu_s: 1.0,
            expected_s: None,
        });
        let pace = busy.wall_per_cpu();
        assert_eq!(pace, 5.0);
        let waited = advice_wall(&busy, &target, &s.known, 3, &[(s.known.clone(), 20)]);
        assert!(waited > 2.0 * plain, "{waited} s at {pace}, {plain} s at 1");
        // from the plain model, a question whose models hold the lag costs as they do
        let asked = advice_wall(&quiet, &target, &s.known, 0, &[(lagged.clone(), 20)]);
        let plainly = advice_wall(&quiet, &target, &s.known, 0, &[(s.known.clone(), 20)]);
        assert!(
            asked > 1.2 * plainly,
            "with the lag {asked} s, without {plainly} s"
        );
    }
}
