//! The advice's recommendation: the cheapest design that answers the record's question
//! safely, or the one that separates its leading models most, and its words in the
//! report.

use hbmodel::Params;

use super::{Advice, Assessed, Scale, Separation, AS_IS, QUESTION_MODEL};
use crate::gap::evidence::CLEAR_LN_BAYES;

/// The pair of `a` whose separation is least.
fn closest(a: &Assessed) -> Option<&Separation> {
    a.pairs
        .iter()
        .min_by(|x, y| x.ln_bayes_factor.total_cmp(&y.ln_bayes_factor))
}

/// Expected ln B a design must reach to be recommended for its shortness: ten times the
/// "clear" level, because the expectation is an upper bound (a refit on the new record
/// takes up part of the difference).
pub const SAFE_LN_BAYES: f64 = 10.0 * CLEAR_LN_BAYES;

/// The shortest design whose closest pair reaches SAFE_LN_BAYES (the cheapest record
/// that answers the question: a 5 s sweep costs the analysis 5-10 times the steps'
/// CPU), the farthest-separating one when none does.
pub(super) fn recommend(
    from: &Params,
    leading: &[(String, Params)],
    scale: Scale,
    designs: Vec<Assessed>,
) -> Advice {
    let least = |a: &Assessed| a.least_ln_bayes_factor.unwrap_or(f64::NEG_INFINITY);
    let safe = designs
        .iter()
        .filter(|a| least(a) >= SAFE_LN_BAYES)
        .min_by(|a, b| {
            a.design
                .duration
                .total_cmp(&b.design.duration)
                .then(least(b).total_cmp(&least(a)))
        });
    let best = safe.or_else(|| {
        designs
            .iter()
            .filter(|a| a.least_ln_bayes_factor.is_some())
            .max_by(|a, b| least(a).total_cmp(&least(b)))
    });
    let (best_label, separates, recommendation) = match best.and_then(|b| Some((b, closest(b)?))) {
        None => (
            None,
            false,
            "nothing to compare: fewer than two leading models, or every simulation failed".into(),
        ),
        Some((b, p)) if p.ln_bayes_factor >= CLEAR_LN_BAYES => (
            Some(b.label.clone()),
            true,
            format!(
                "measure {}: it separates every pair of the leading models, the closest ({} and {}) by {:.2} noise levels RMS, expected ln B {}",
                b.label, p.a, p.b, p.rms, number(p.ln_bayes_factor)
            ),
        ),
        Some((b, p)) => (
            Some(b.label.clone()),
            false,
            format!(
                "none of the experiments separates {} from {} (expected ln B < {CLEAR_LN_BAYES}); the best, {}, reaches ln B {:.2} ({:.3} noise levels RMS)",
                p.a, p.b, b.label, p.ln_bayes_factor, p.rms
            ),
        ),
    };
    Advice {
        question: format!(
            "the record leaves the leading models undecided: {}",
            leading
                .iter()
                .map(|(n, _)| format!("`{n}`"))
                .collect::<Vec<_>>()
                .join(", ")
        ),
        leading: leading.iter().map(|(n, _)| n.clone()).collect(),
        tau: scale.tau,
        misfit: scale.misfit,
        designs,
        best: best_label,
        separates,
        recommendation,
        between: leading
            .iter()
            .map(|(n, _)| n.clone())
            .filter(|n| n != AS_IS)
            .collect(),
        from: from.clone(),
        recalibrate: Vec::new(),
    }
}

/// A Bayes factor for a person: 1 decimal, or 3 digits with an exponent when large.
fn number(x: f64) -> String {
    if x.abs() < 1e5 {
        format!("{x:.1}")
    } else {
        format!("{x:.2e}")
    }
}

/// The report's "What to measure next" section.
pub fn markdown(a: &Advice) -> String {
    let mut md = format!(
        "\n## What to measure next\n\nOn this record {}. \
         Each model was simulated, noise-free, under every experiment design; the separation \
         is the RMS difference in noise levels of y, P1, P2 over n samples that is left once \
         each model is re-fitted to the other's run (its own parameters and the known model's \
         recalibrations, to first order within their bounds; report.json gives the share \
         taken up as `absorbed`), and the expected \
         ln B = (n / tau) / 2 ln(1 + chi-square difference / (n m)), with the residual's \
         correlation time tau = {:.1} and its misfit m = {:.2} (the gap squared) as the record \
         showed. A design the records hold is read at no more than the ln B they showed \
         (marked *recorded*, with what the simulations promised).\n\n| design |",
        a.question, a.tau, a.misfit
    );
    let pairs: Vec<String> = a
        .designs
        .iter()
        .find(|d| d.error.is_none())
        .map(|d| {
            d.pairs
                .iter()
                .map(|p| format!("{} / {}", p.a, p.b))
                .collect()
        })
        .unwrap_or_default();
    for p in &pairs {
        md.push_str(&format!(" {p}: RMS, ln B |"));
    }
    md.push_str(&format!("\n|---|{}\n", "---|".repeat(pairs.len())));
    for d in &a.designs {
        md.push_str(&format!("| {} |", d.label));
        match &d.error {
            Some(e) => md.push_str(&format!(
                " not assessed: {e} |{}",
                " |".repeat(pairs.len().saturating_sub(1))
            )),
            None => {
                for p in &d.pairs {
                    let mark = if p.recorded.is_some() {
                        format!(" *recorded* (simulated {})", number(p.simulated))
                    } else {
                        String::new()
                    };
                    md.push_str(&format!(
                        " {:.3}, {}{mark} |",
                        p.rms,
                        number(p.ln_bayes_factor)
                    ));
                }
            }
        }
        md.push('\n');
    }
    md.push_str(&format!("\n**Recommendation:** {}.\n", a.recommendation));
    if a.best.is_some() && !a.between.is_empty() {
        md.push_str(&format!(
            "\nOn the new record, `hbench gap --data NEW.csv --experiment NEW.toml --model {QUESTION_MODEL} --between {}{}` \
             fits only these candidates from the model the question starts from ({QUESTION_MODEL}, written beside this report), \
             with the parameters this run recalibrated re-fitted, and says which one the record prefers.\n",
            a.between.join(","),
            recalibrate_option(a)
        ));
    }
    md
}

/// The `--recalibrate` option of the command that decides the question (empty when the
/// run recalibrated nothing).
pub fn recalibrate_option(a: &Advice) -> String {
    if a.recalibrate.is_empty() {
        String::new()
    } else {
        format!(" --recalibrate {}", a.recalibrate.join(","))
    }
}
