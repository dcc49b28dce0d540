//! A design the records already hold. The leading models were fitted to those records
//! and each bent its parameters to them, so under the records' own design the two stay
//! about as close as the records showed: a new record of it brings the same model-form
//! error and leaves the same question. Four of six advised designs on the peer's steps
//! were the first record's own +-10 mm steps; the advice expected ln B 77-338 from them,
//! and the decisions found 4.2-9.7 (docs/gap.md, session 20). The separation expected
//! under such a design is read as no more than the records showed.

use super::super::experiments::Design;
use super::super::fit::Fit;
use super::{Assessed, AS_IS};

/// The ln B between two leading models that the round which fitted them showed:
/// half their score difference (`evidence::preference`). The model as it stands scores
/// 0 against the round's start, or the score of `accepted`, the round's winner it took.
pub fn observed(fits: &[(f64, Fit)], accepted: Option<&str>, a: &str, b: &str) -> Option<f64> {
    let score = |name: &str| {
        let name = if name == AS_IS {
            match accepted {
                Some(winner) => winner,
                None => return Some(0.0),
            }
        } else {
            name
        };
        fits.iter()
            .find(|(_, f)| f.name == name)
            .map(|(s, _)| *s)
            .filter(|s| s.is_finite())
    };
    Some((score(a)? - score(b)?).abs() / 2.0)
}

/// Each design of `assessed` that is one of `recorded`: every pair read at no more than
/// the ln B `observed` gives it, and its least separation again.
pub fn read_at_records(
    assessed: &mut [Assessed],
    recorded: &[Design],
    observed: impl Fn(&str, &str) -> Option<f64>,
) {
    for d in assessed.iter_mut().filter(|d| recorded.contains(&d.design)) {
        for p in &mut d.pairs {
            if let Some(shown) = observed(&p.a, &p.b) {
                p.recorded = Some(shown);
                p.ln_bayes_factor = p.ln_bayes_factor.min(shown);
            }
        }
        if d.error.is_none() {
            d.least_ln_bayes_factor = d
                .pairs
                .iter()
                .map(|p| p.ln_bayes_factor)
                .min_by(f64::total_cmp);
        }
    }
}
