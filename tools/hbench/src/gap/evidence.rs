//! Evidence between hypotheses that holds when no hypothesis is the truth.
//!
//! Under model-form error the residual that no candidate removes is many times the noise
//! and strongly coloured: a chi-square drop against white noise then reaches 1e7 and every
//! candidate "pays" its price. Two guards replace it:
//!
//! - each hypothesis is fitted on one half of the samples (alternate blocks, see
//!   `fit::Part`) and judged on the other, which it did not see;
//! - the judged residuals are counted by their effective number, N / tau, tau the
//!   integrated autocorrelation time of the residual the best hypothesis leaves, and their
//!   variance is not assumed to be the noise's: the Gaussian log-likelihood with the
//!   variance profiled out gives 2 ln L = -N_eff ln(chi2), so a hypothesis scores
//!   N_eff ln(chi2_before / chi2_after) - k ln N_eff (the Bayesian information criterion
//!   on the effective count). On white residuals at the noise floor this is the old
//!   chi-square drop less k ln N.
//!
//! Between two hypotheses, half the difference of their scores is the log of a Bayes
//! factor (Schwarz's approximation), printed as a ratio and as a weight.

use nalgebra::DVector;
use serde::Serialize;

use super::fit::{Part, Target};

/// Largest lag (samples) of the autocorrelation sum: 0.2 s at 1 kHz, several periods of
/// the slowest oscillation a residual of these experiments carries.
const MAX_LAG: usize = 200;

/// A Bayes factor below this between the two leading hypotheses is reported as "cannot
/// tell A from B": 10 is the threshold of "strong" evidence on Jeffreys' scale.
pub const DECISIVE_RATIO: f64 = 10.0;

/// Integrated autocorrelation time of a series (samples; 1 for white noise), by Geyer's
/// initial positive sequence: the sums of adjacent autocorrelation pairs are added while
/// they stay positive, which stops the sum before the estimate's own noise dominates.
pub fn correlation_time(x: &[f64]) -> f64 {
    let n = x.len();
    if n < 4 {
        return 1.0;
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let d: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let c0 = d.iter().map(|v| v * v).sum::<f64>();
    if c0 <= 0.0 {
        return 1.0;
    }
    let rho = |k: usize| {
        d[..n - k]
            .iter()
            .zip(&d[k..])
            .map(|(a, b)| a * b)
            .sum::<f64>()
            / c0
    };
    let mut tau = -1.0; // -rho_0: the pairs (rho_0 + rho_1), ... count rho_0 twice
    let mut k = 0;
    while k + 1 < MAX_LAG.min(n - 1) {
        let pair = rho(k) + rho(k + 1);
        if pair <= 0.0 {
            break;
        }
        tau += 2.0 * pair;
        k += 2;
    }
    tau.max(1.0)
}

/// Effective number of independent residuals in `part`: each (record, signal) series
/// counts its samples in the part divided by its correlation time.
pub fn effective_count(target: &Target, residuals: &DVector<f64>, part: Part) -> f64 {
    let mask = target.mask(part);
    let masks = target.series(&mask);
    target
        .series(residuals)
        .iter()
        .zip(masks)
        .map(|(r, m)| m.iter().sum::<f64>() / correlation_time(r))
        .sum::<f64>()
        .max(1.0)
}

/// Sum of squares of the residuals in `part`.
pub fn chi2(target: &Target, residuals: &DVector<f64>, part: Part) -> f64 {
    residuals.component_mul(&target.mask(part)).norm_squared()
}

/// The score of a hypothesis with `k` parameters that takes the judged chi-square from
/// `before` to `after` on `n_eff` effective samples (see the module's comment).
pub fn score(before: f64, after: f64, k: usize, n_eff: f64) -> f64 {
    if !(after.is_finite() && after > 0.0) {
        return f64::NEG_INFINITY;
    }
    n_eff * (before / after).ln() - k as f64 * n_eff.ln()
}

/// The evidence for the leading hypothesis against the next one, readable by a person.
#[derive(Debug, Clone, Serialize)]
pub struct Evidence {
    pub leader: String,
    pub runner_up: Option<String>,
    /// Bayes factor of the leader over the runner-up (Schwarz's approximation).
    pub ratio: Option<f64>,
    /// The leader's posterior weight among all hypotheses and "change nothing", equal
    /// priors.
    pub weight: f64,
    /// Effective number of independent judged residuals.
    pub effective_samples: f64,
    /// Whether the leader is told apart from the runner-up (ratio >= DECISIVE_RATIO).
    pub decisive: bool,
    pub statement: String,
}

/// Evidence among scored hypotheses (label, score), the best first.
pub fn evidence(ranked: &[(String, f64)], n_eff: f64) -> Option<Evidence> {
    let (leader, best) = ranked.first()?;
    // weights relative to the leader, "change nothing" scoring 0
    let rel = |s: f64| ((s - best) / 2.0).exp();
    let total: f64 = ranked.iter().map(|(_, s)| rel(*s)).sum::<f64>() + rel(0.0);
    let weight = 1.0 / total;
    let second = ranked.get(1);
    let ratio = second.map(|(_, s)| ((best - s) / 2.0).exp());
    let decisive = ratio.is_none_or(|r| r >= DECISIVE_RATIO);
    let statement = match (second, ratio) {
        (Some((b, _)), Some(r)) if !decisive => format!(
            "cannot tell {leader} from {b} on this record (Bayes factor {r:.2} on {n_eff:.0} effective samples)"
        ),
        (Some((b, _)), Some(r)) => format!(
            "{leader} over {b}: Bayes factor {} on {n_eff:.0} effective samples (weight {weight:.3})",
            readable(r)
        ),
        _ => format!("{leader} alone (weight {weight:.3})"),
    };
    Some(Evidence {
        leader: leader.clone(),
        runner_up: second.map(|(b, _)| b.clone()),
        ratio,
        weight,
        effective_samples: n_eff,
        decisive,
        statement,
    })
}

/// A ratio as a person reads it: plain below a million, a power of ten above.
fn readable(r: f64) -> String {
    if r < 1e6 {
        format!("{r:.1}")
    } else if r.is_finite() {
        format!("1e{:.0}", r.log10())
    } else {
        "beyond 1e300".into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn correlation_time_of_white_and_of_filtered_noise() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let n = Normal::new(0.0, 1.0).unwrap();
        let white: Vec<f64> = (0..20000).map(|_| n.sample(&mut rng)).collect();
        let t = correlation_time(&white);
        assert!((t - 1.0).abs() < 0.15, "white: {t}");
        // first-order autoregression x_k = a x_(k-1) + e_k: tau = (1 + a) / (1 - a)
        let a: f64 = 0.8;
        let mut x = 0.0;
        let ar: Vec<f64> = white
            .iter()
            .map(|e| {
                x = a * x + e;
                x
            })
            .collect();
        let t = correlation_time(&ar);
        let expected = (1.0 + a) / (1.0 - a);
        assert!(
            (t / expected - 1.0).abs() < 0.2,
            "AR(1): {t} against {expected}"
        );
    }

    #[test]
    fn evidence_says_when_it_cannot_tell() {
        let close = [("a".to_string(), 30.0), ("b".to_string(), 28.0)];
        let e = evidence(&close, 100.0).unwrap();
        assert!(
            !e.decisive && e.statement.contains("cannot tell a from b"),
            "{e:?}"
        );
        assert!((e.ratio.unwrap() - 1f64.exp()).abs() < 1e-12);
        let far = [("a".to_string(), 30.0), ("b".to_string(), 10.0)];
        let e = evidence(&far, 100.0).unwrap();
        assert!(e.decisive && e.weight > 0.99, "{e:?}");
    }
}
