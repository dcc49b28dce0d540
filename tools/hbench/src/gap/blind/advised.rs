//! A case's experiment advice put to the test (issue 14 item 6): the bench recorded
//! again under the design the workflow recommended, that record analysed afresh and the
//! advice's question decided on it.

use std::path::Path;

use hbmodel::effects::Effect;
use hbmodel::sensors::SensorParams;
use hbmodel::Params;

use super::super::advice::Advice;
use super::super::experiments::Design;
use super::super::hide::measure_design;
use super::super::{decision, run_with, Record, Settings};
use super::{fitted_of, named, Case, Setup};

/// The advice a case's analysis gave and the design it recommended, to be recorded.
pub struct Followed<'a> {
    pub advice: &'a Advice,
    pub design: Design,
    pub expected: Option<f64>,
    pub seed: u64,
    pub settings: Settings,
}

impl Followed<'_> {
    /// The bench recorded under the design (new noise); the record analysed afresh, as
    /// a user without the question would, and the advice's question decided on it.
    /// With `keep_in`, the record (measured.csv, experiment.toml) and the afresh
    /// analysis's report are kept there: where the afresh analysis and the decision
    /// disagree (the Rust moves' hidden air, seed 2: nothing named afresh, the air
    /// decided by ln B 480, session 53), `hbench gap` can be run on that record again.
    pub fn record(
        &self,
        case: &mut Case,
        (s, first): (&Setup, &[Record]),
        base: &Params,
        hidden: &[Effect],
        (path, keep_in): (&str, Option<&Path>),
    ) -> Result<(), String> {
        let sp = SensorParams {
            seed: self.seed + ADVISED_SEED,
            ..SensorParams::default()
        };
        let (experiment, measured) = measure_design(&s.bench, &self.design, &sp)?;
        let record = Record {
            name: self.design.label(),
            experiment,
            measured,
        };
        let again = run_with(
            base,
            std::slice::from_ref(&record),
            Settings {
                advise: false,
                ..self.settings
            },
        )?;
        // a user who holds the first record too analyses both at once (item 3): the
        // first record pins what it showed (its recalibrations at the thesis's supply),
        // the advised one what the first could not show
        let mut both = first.to_vec();
        both.push(record.clone());
        let jointly = run_with(
            base,
            &both,
            Settings {
                advise: false,
                ..self.settings
            },
        )?;
        let (decision, _) = decision::decide(
            &self.advice.from,
            &self.advice.between,
            &self.advice.recalibrate,
            std::slice::from_ref(&record),
            self.settings.within,
            false,
        )?;
        if let Some(dir) = keep_in {
            keep(dir, &record, &again)?;
        }
        // written only once every part has succeeded: a case whose advice failed is
        // counted with the failures, never also with the records analysed
        case.named_after_advice = Some(named(&again, base, hidden));
        case.named_jointly = Some(named(&jointly, base, hidden));
        case.fitted_after_advice = fitted_of(&again, base, hidden, path).0;
        case.decided = decision.winner.clone();
        case.advice_between = self.advice.between.clone();
        case.expected_ln_bayes = self.expected;
        case.found_ln_bayes = decision.preference.as_ref().map(|p| p.ln_bayes_factor);
        case.decision = serde_json::to_value(&decision).ok();
        Ok(())
    }
}

/// Write the advised record as `hbench hide` writes one, and its afresh analysis's report
/// as `hbench gap` does, in `dir` (a study's own directory, written afresh each run).
fn keep(dir: &Path, record: &Record, outcome: &super::super::Outcome) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let write = |name: &str, text: String| {
        let f = dir.join(name);
        std::fs::write(&f, text).map_err(|e| format!("cannot write {}: {e}", f.display()))
    };
    write("measured.csv", record.measured.to_csv())?;
    write("experiment.toml", record.experiment.to_toml())?;
    super::super::report::write(dir, outcome, None)
}

/// The ln B the advice expects of the decision on a record of `d`: the least over the
/// pairs of candidates the decision asks between (`Advice::between`). Not the design's
/// least over every pair: for a record explained within its noise that is the model as
/// it stands against an unseen effect, which the decision never compares (sessions 53-54
/// compared the decision's found ln B, 4-454 on the Rust moves' 50 bar steps, with
/// 1220-1306 expected of the model as it stands against the air; of the volume against
/// the air it is 1730-1794, measured in session 55).
fn decided_pair(a: &Advice, d: &super::super::advice::Assessed) -> Option<f64> {
    let asked = |name: &String| a.between.contains(name);
    d.pairs
        .iter()
        .filter(|p| asked(&p.a) && asked(&p.b))
        .map(|p| p.ln_bayes_factor)
        .min_by(f64::total_cmp)
        .or(d.least_ln_bayes_factor)
}

/// Offset of the advised record's noise seed from the case's: a new record, new noise.
const ADVISED_SEED: u64 = 2000;

/// Follow the `advice` a case's analysis gave (its hidden effect not named first): record
/// the recommended design and analyse it (`Followed::record`). A design is recommended
/// only when it separates the question; the best of the designs when none does is no
/// recommendation, recording it tests nothing, and the case keeps the advice's words in
/// `unadvised`. With `keep_in` the advised record and its analysis are kept there
/// (`Followed::record`). A bench that cannot record the design (the peer's solver stopping)
/// leaves the case as its first record made it, the failure said and counted apart.
pub fn follow(
    case: &mut Case,
    advice: Option<&Advice>,
    (s, first): (&Setup, &[Record]),
    hidden: &[Effect],
    seed: u64,
    settings: Settings,
    (path, keep_in): (&str, Option<&Path>),
) {
    let recommended = advice.filter(|a| a.separates).and_then(|a| {
        let best = a.best.as_ref()?;
        let d = a.designs.iter().find(|d| &d.label == best)?;
        Some((a, d.design, decided_pair(a, d)))
    });
    let Some((advice, design, expected)) = recommended else {
        case.unadvised = advice.map(|a| a.recommendation.clone());
        return;
    };
    case.advised = Some(design.label());
    let followed = Followed {
        advice,
        design,
        expected,
        seed,
        settings,
    };
    if let Err(e) = followed.record(case, (s, first), &s.known, hidden, (path, keep_in)) {
        eprintln!("{}: the advised record failed: {e}", design.label());
        case.advice_failed = Some(e);
    }
}
