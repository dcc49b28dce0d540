//! One case of a blind study as `blind.json` keeps it: what was hidden, what the
//! workflow named and fitted, and how the case was judged.

use serde::Serialize;

use super::super::variants::Simulator;
use super::rivals;

#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct Case {
    pub hidden: Vec<String>,
    pub experiment: String,
    pub seed: u64,
    /// Effects the workflow added, in order.
    pub named: Vec<String>,
    /// Parameters re-fitted as recalibration steps (counted apart from the named effects).
    #[serde(default)]
    pub recalibrated: Vec<String>,
    /// The first hidden effect's first parameter: truth and fit (none with nothing
    /// hidden), as the step that named the effect fitted it.
    pub truth: Option<f64>,
    pub fitted: Option<f64>,
    /// The same parameter in the run's final model, the fitted_model.toml a user gets
    /// (later steps re-fit it beside theirs); with `fitted` only (absent in studies run
    /// before it was recorded).
    #[serde(default)]
    pub fitted_at_end: Option<f64>,
    /// The fit's standard error (`fit::spread`; absent in studies run before it was
    /// recorded).
    #[serde(default)]
    pub fitted_std: Option<f64>,
    /// The fitted parameter the record trades that fit against most (`fit::spread`), with
    /// their correlation: a record that cannot set the two apart biases both.
    #[serde(default)]
    pub fitted_traded: Option<(String, f64)>,
    pub initial_gap: f64,
    pub remaining_gap: f64,
    /// Mean square, over the compared samples, of what the hidden effects change in the
    /// noise-free signals, in units of the true sensor noise (absent in studies run before
    /// it was recorded).
    #[serde(default)]
    pub visibility: Option<f64>,
    /// Whether an ideal fit (the truth itself) would pass the workflow's acceptance rules:
    /// its chi-square drop pays k ln N and it lowers the gap by MIN_IMPROVEMENT.
    #[serde(default)]
    pub identifiable: Option<bool>,
    /// The bench that made the data: "rust" (the model) or "peer" (tools/peer).
    #[serde(default = "rust_name")]
    pub simulator: String,
    /// Whether a model-form error was drawn (then the known model is section 4.4's).
    #[serde(default)]
    pub form_error: bool,
    /// The form error drawn (variants::FormError::to_json), when there is one.
    #[serde(default)]
    pub form: Option<serde_json::Value>,
    /// When the study follows the advice and the first record did not name the hidden
    /// effect first: the design the workflow recommended, and what a record of it named.
    #[serde(default)]
    pub advised: Option<String>,
    #[serde(default)]
    pub named_after_advice: Option<Vec<String>>,
    /// What the advised record named analysed together with the case's first records
    /// (several records in one analysis, item 3): what a user holding both would run.
    #[serde(default)]
    pub named_jointly: Option<Vec<String>>,
    /// Why the bench could not record the advised design, when it could not.
    #[serde(default)]
    pub advice_failed: Option<String>,
    /// The advice's own words when it recommended no design (none separates its
    /// question): there is nothing to record, and the case is counted apart.
    #[serde(default)]
    pub unadvised: Option<String>,
    /// The first hidden effect's first parameter as that record's analysis fitted it.
    #[serde(default)]
    pub fitted_after_advice: Option<f64>,
    /// What the question, decided on the advised record, named (`decision::decide`).
    #[serde(default)]
    pub decided: Option<String>,
    /// The candidates the advice asked to decide between, the separation it expected
    /// (least ln B over their pairs) and the ln B the decision found between its best and
    /// runner-up (the model as it stands among them).
    #[serde(default)]
    pub advice_between: Vec<String>,
    #[serde(default)]
    pub expected_ln_bayes: Option<f64>,
    #[serde(default)]
    pub found_ln_bayes: Option<f64>,
    /// The decision in full (`decision::Decision`): each candidate's fit, the held-out
    /// checks, the verdict.
    #[serde(default)]
    pub decision: Option<serde_json::Value>,
    /// Effects that won a round but were refused on the data they were not fitted on.
    #[serde(default)]
    pub refused: Vec<String>,
    /// A contested step asked again at the end of the run (`revision::Revision`).
    #[serde(default)]
    pub revision: Option<serde_json::Value>,
    /// The hidden effect against its closest rival on the noise-free record
    /// (`rivals`; single hidden effects only, absent in studies run before it).
    #[serde(default)]
    pub rivalry: Option<rivals::Rivalry>,
    /// The same judgement made on the bench's own noise-free record, every recalibration
    /// re-fitted beside each candidate (`on_record`; absent in studies run before session
    /// 41 and until `blind --summarise --on-record` judges them).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rivalry_on_record: Option<rivals::Rivalry>,
    /// CPU seconds the analysis of the case's records took (every thread; the advised
    /// record's analysis and the rivals' judgement not counted): what a user waits for,
    /// issue 14 item 7.
    #[serde(default)]
    pub cpu_seconds: Option<f64>,
    /// The relative tolerance the analysis simulated at (`gap --rtol`; absent in studies
    /// run before it was recorded, which ran at the default of their day).
    #[serde(default)]
    pub rtol: Option<f64>,
}

fn rust_name() -> String {
    Simulator::Rust.name().into()
}

impl Case {
    /// The first effect named is a hidden one (with none hidden: nothing is named).
    pub fn first_correct(&self) -> bool {
        match self.named.first() {
            Some(n) => self.hidden.contains(n),
            None => self.hidden.is_empty(),
        }
    }
    /// Every hidden effect is named, and with none hidden nothing is.
    pub fn all_found(&self) -> bool {
        self.hidden.iter().all(|h| self.named.contains(h))
            && (!self.hidden.is_empty() || self.named.is_empty())
    }
    /// Identifiable, and told from every rival (`rivals`); None when not judged.
    pub fn told_from_rivals(&self) -> Option<bool> {
        let r = self.rivalry.as_ref()?;
        Some(self.identifiable == Some(true) && r.told())
    }
    /// Identifiable, and told from every rival on the bench's own record (`on_record`);
    /// None when not judged so.
    pub fn told_on_record(&self) -> Option<bool> {
        let r = self.rivalry_on_record.as_ref()?;
        Some(self.identifiable == Some(true) && r.told())
    }
    pub fn magnitude_error(&self) -> Option<f64> {
        Some((self.fitted? / self.truth? - 1.0).abs())
    }
    /// `magnitude_error` of the final model's value (`fitted_at_end`).
    pub fn magnitude_error_at_end(&self) -> Option<f64> {
        Some((self.fitted_at_end? / self.truth? - 1.0).abs())
    }
    pub fn shrink(&self) -> f64 {
        // the gap above the noise floor that the added effects closed
        let above = |g: f64| (g - 1.0).max(0.0);
        if above(self.initial_gap) == 0.0 {
            return 1.0;
        }
        1.0 - above(self.remaining_gap) / above(self.initial_gap)
    }
}
