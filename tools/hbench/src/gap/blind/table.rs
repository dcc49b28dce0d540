//! The blind study's table: rates per hidden effect and bench, over all cases and over
//! the identifiable ones.

use std::fmt::Write as _;
use std::path::Path;

use super::{rivals, Case};

fn rate(cases: &[&Case], f: impl Fn(&Case) -> bool) -> String {
    if cases.is_empty() {
        return "-".into();
    }
    let k = cases.iter().filter(|c| f(c)).count();
    format!(
        "{:.0} % ({k}/{})",
        100.0 * k as f64 / cases.len() as f64,
        cases.len()
    )
}

/// The bench a case's data came from, as the table names it.
fn bench_label(c: &Case) -> String {
    match (c.simulator.as_str(), c.form_error) {
        ("rust", false) => String::new(),
        (s, true) => format!(" ({s}, form error)"),
        (s, false) => format!(" ({s})"),
    }
}

/// Markdown summary: per hidden effect and bench, per bench and overall. Rates are given
/// over all cases and over the identifiable ones (an ideal fit of the truth would pass
/// the acceptance rules on that record).
pub fn table(cases: &[Case]) -> String {
    let mut md = String::from(
        "| hidden | cases | first named correctly | all hidden found | fitted within 20 % | median gap closed | identifiable | first named, identifiable | all found, identifiable | fitted within 25 %, identifiable |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let label = |c: &Case| {
        let hidden = if c.hidden.is_empty() {
            "none".to_string()
        } else {
            c.hidden.join(" + ")
        };
        hidden + &bench_label(c)
    };
    let mut groups: Vec<String> = cases.iter().map(label).collect();
    groups.dedup();
    groups.sort();
    groups.dedup();
    let row = |md: &mut String, name: &str, sel: Vec<&Case>| {
        let mut shrink: Vec<f64> = sel.iter().map(|c| c.shrink()).collect();
        shrink.sort_by(f64::total_cmp);
        let median = shrink.get(shrink.len() / 2).copied().unwrap_or(f64::NAN);
        // the cases with an effect hidden whose data show it (recorded ones only)
        let shown: Vec<&Case> = sel
            .iter()
            .copied()
            .filter(|c| !c.hidden.is_empty() && c.identifiable == Some(true))
            .collect();
        let recorded = sel
            .iter()
            .filter(|c| !c.hidden.is_empty() && c.identifiable.is_some())
            .count();
        let _ = writeln!(
            md,
            "| {name} | {} | {} | {} | {} | {:.0} % | {} | {} | {} | {} |",
            sel.len(),
            rate(&sel, Case::first_correct),
            rate(&sel, Case::all_found),
            rate(
                &sel.iter()
                    .copied()
                    .filter(|c| !c.hidden.is_empty())
                    .collect::<Vec<_>>(),
                |c| c.magnitude_error().is_some_and(|e| e <= 0.2)
            ),
            100.0 * median,
            if recorded == 0 {
                "-".to_string()
            } else {
                format!("{}/{recorded}", shown.len())
            },
            rate(&shown, Case::first_correct),
            rate(&shown, Case::all_found),
            rate(&shown, |c| c.magnitude_error().is_some_and(|e| e <= 0.25)),
        );
    };
    for g in &groups {
        row(
            &mut md,
            g,
            cases.iter().filter(|c| &label(c) == g).collect(),
        );
    }
    let mut benches: Vec<String> = cases.iter().map(bench_label).collect();
    benches.sort();
    benches.dedup();
    if benches.len() > 1 {
        for b in &benches {
            let name = format!("**all{}**", if b.is_empty() { " (rust)" } else { b });
            row(
                &mut md,
                &name,
                cases.iter().filter(|c| &bench_label(c) == b).collect(),
            );
        }
    }
    row(&mut md, "**all**", cases.iter().collect());
    md.push_str(&rivals_line(cases, Judge::Transplant));
    md.push_str(&rivals_line(cases, Judge::OnRecord));
    md.push_str(&cpu_line(cases));
    md.push_str(&rtol_line(cases));
    md.push_str(&end_line(cases));
    md.push_str(&advice_line(cases));
    md.push_str(&revision_line(cases));
    md.push_str(&spread_line(cases));
    md
}

/// How far each fitted magnitude lies from the truth in its own standard errors
/// (`fit::spread`): the spread covers the noise, not the bias a model-form error puts in
/// a fit (empty when no case recorded one).
fn spread_line(cases: &[Case]) -> String {
    let off: Vec<(&Case, f64)> = cases
        .iter()
        .filter_map(|c| {
            let (f, t, d) = (c.fitted?, c.truth?, c.fitted_std?);
            (d > 0.0).then(|| (c, (f - t) / d))
        })
        .collect();
    if off.is_empty() {
        return String::new();
    }
    let within = off.iter().filter(|(_, z)| z.abs() <= 2.0).count();
    let mut line = format!(
        "\nThe truth within two standard errors of the fit: {within} of {} fitted.\n",
        off.len()
    );
    for (c, z) in off {
        let _ = writeln!(
            line,
            "- {}: {:.4e} +- {:.2e} against {:.4e} ({z:+.1} s.e.)",
            label(c),
            c.fitted.unwrap_or_default(),
            c.fitted_std.unwrap_or_default(),
            c.truth.unwrap_or_default()
        );
    }
    line
}

/// The runs whose step was asked again at their end (`revision`: contested, moved by the
/// run, or taken clearly by a run that ended far above the floor), and what came of it
/// (empty when none was).
fn revision_line(cases: &[Case]) -> String {
    let asked: Vec<(&Case, &serde_json::Value)> = cases
        .iter()
        .filter_map(|c| Some((c, c.revision.as_ref()?)))
        .collect();
    if asked.is_empty() {
        return String::new();
    }
    let kept = asked
        .iter()
        .filter(|(_, r)| r["revised"].as_bool() == Some(true))
        .count();
    let mut line = format!(
        "\nAsked again at the end of the run (a contested step, an added effect whose size the \
         run moved by more than 25 %, or any step when the run ended far above the noise floor, \
         with the later recalibrations re-fitted): {} runs, continued from the rival and kept in {kept}.\n",
        asked.len()
    );
    let added = |p: &serde_json::Value| {
        let names: Vec<&str> = p["added"]
            .as_array()
            .map(|a| a.iter().filter_map(|n| n.as_str()).collect())
            .unwrap_or_default();
        if names.is_empty() {
            "nothing".to_string()
        } else {
            names.join(", ")
        }
    };
    for (c, r) in asked {
        let _ = writeln!(
            line,
            "- {}: step {}{} between {}: {} (ln B {}); added {} -> {}{}",
            label(c),
            r["step"].as_u64().map_or(0, |k| k + 1),
            // studies before the reason was recorded asked contested steps only
            if r["reason"].as_str().is_some_and(|w| w != "contested") {
                " (taken clearly)"
            } else {
                ""
            },
            r["between"]
                .as_array()
                .map(|a| a
                    .iter()
                    .filter_map(|n| n.as_str())
                    .collect::<Vec<_>>()
                    .join(" or "))
                .unwrap_or_default(),
            r["decision"]["winner"].as_str().unwrap_or("nothing"),
            ln_b(r["decision"]["preference"]["ln_bayes_factor"].as_f64()),
            added(&r["original"]),
            if r["continued"].is_null() {
                "(not continued)".to_string()
            } else {
                added(&r["continued"])
            },
            if r["revised"].as_bool() == Some(true) {
                " (kept)"
            } else {
                ""
            }
        );
    }
    line
}

/// Which judgement of identifiability a table line reads.
#[derive(Clone, Copy)]
enum Judge {
    /// `rivals`: the signature transplanted onto the recalibrated known model's record.
    Transplant,
    /// `on_record`: the bench's own record, every recalibration beside each candidate.
    OnRecord,
}

impl Judge {
    fn of(self, c: &Case) -> Option<&rivals::Rivalry> {
        match self {
            Judge::Transplant => c.rivalry.as_ref(),
            Judge::OnRecord => c.rivalry_on_record.as_ref(),
        }
    }

    fn told(self, c: &Case) -> Option<bool> {
        match self {
            Judge::Transplant => c.told_from_rivals(),
            Judge::OnRecord => c.told_on_record(),
        }
    }

    fn title(self) -> &'static str {
        match self {
            Judge::Transplant => "Told from its rivals (the hidden effect's fit beats every other candidate's and \
                 recalibration's by ln B 3 in 9 records of 10, on the known model's noise-free record \
                 with the effect's signature on the bench added, the form error's residual beside each)",
            Judge::OnRecord => "Told from its rivals on the bench's own record (the same test, each candidate \
                 fitted to the bench's noise-free record with the effect and its form error, every \
                 recalibration of the known model re-fitted beside it)",
        }
    }
}

/// The identifiable cases judged against their rivals by `judge`, how many of them the
/// record tells from every rival, and how the workflow named those, over all and per
/// hidden effect (empty when no case was judged so).
fn rivals_line(cases: &[Case], judge: Judge) -> String {
    let judged: Vec<&Case> = cases
        .iter()
        .filter(|c| c.identifiable == Some(true) && judge.of(c).is_some())
        .collect();
    if judged.is_empty() {
        return String::new();
    }
    let all_told: Vec<&Case> = judged
        .iter()
        .copied()
        .filter(|c| judge.told(c) == Some(true))
        .collect();
    let mut line = format!(
        "\n{}: {} of {} identifiable cases; on those, named first {}, fitted within 25 % {}.\n",
        judge.title(),
        all_told.len(),
        judged.len(),
        rate(&all_told, Case::first_correct),
        rate(&all_told, |c| c
            .magnitude_error()
            .is_some_and(|e| e <= 0.25)),
    );
    // the hidden effect is listed last, after what it brought along
    let mut effects: Vec<&str> = judged
        .iter()
        .filter_map(|c| c.hidden.last().map(String::as_str))
        .collect();
    effects.sort();
    effects.dedup();
    let per: Vec<String> = effects
        .iter()
        .map(|e| {
            let of: Vec<&Case> = all_told
                .iter()
                .copied()
                .filter(|c| c.hidden.last().map(String::as_str) == Some(*e))
                .collect();
            format!("{e} {}", rate(&of, Case::first_correct))
        })
        .collect();
    let _ = writeln!(
        line,
        "Named first per effect, told cases: {}.",
        per.join("; ")
    );
    for c in judged {
        let Some(r) = judge.of(c) else { continue };
        let _ = writeln!(
            line,
            "- {} #{}: closest rival {} (gap {:.3} against {:.3}, form error {:.2}), ln B {:.1} +- {:.1}{}; named first: {}",
            label(c),
            c.seed,
            r.rival,
            r.rival_gap,
            r.hidden_gap,
            r.form_gap,
            r.ln_bayes,
            r.ln_bayes_sd,
            if r.told() { "" } else { " (not told)" },
            c.named.first().map_or("nothing", String::as_str)
        );
    }
    line
}

/// CPU seconds of the cases' analyses per experiment (issue 14 item 7: a 2 s record in
/// 60 s on two cores), median and largest; empty for studies run before it was recorded.
fn cpu_line(cases: &[Case]) -> String {
    let mut kinds: Vec<&str> = cases
        .iter()
        .filter(|c| c.cpu_seconds.is_some())
        .map(|c| c.experiment.as_str())
        .collect();
    kinds.sort();
    kinds.dedup();
    if kinds.is_empty() {
        return String::new();
    }
    let per: Vec<String> = kinds
        .iter()
        .map(|k| {
            let mut t: Vec<f64> = cases
                .iter()
                .filter(|c| c.experiment == *k)
                .filter_map(|c| c.cpu_seconds)
                .collect();
            t.sort_by(f64::total_cmp);
            format!(
                "{k} median {:.0} s, largest {:.0} s over {}",
                t[t.len() / 2],
                t[t.len() - 1],
                t.len()
            )
        })
        .collect();
    format!(
        "\nCPU time of an analysis (every thread): {}.\n",
        per.join("; ")
    )
}

/// The tolerances the cases' analyses simulated at (`blind --rtol`), with how many
/// cases each: a study merged from runs at two tolerances says so. Empty when no case
/// recorded it.
fn rtol_line(cases: &[Case]) -> String {
    let mut tols: Vec<f64> = cases.iter().filter_map(|c| c.rtol).collect();
    if tols.is_empty() {
        return String::new();
    }
    tols.sort_by(f64::total_cmp);
    tols.dedup();
    let per: Vec<String> = tols
        .iter()
        .map(|t| {
            let n = cases.iter().filter(|c| c.rtol == Some(*t)).count();
            format!("rtol {t:e} ({n} cases)")
        })
        .collect();
    let unrecorded = cases.iter().filter(|c| c.rtol.is_none()).count();
    let before = if unrecorded > 0 {
        format!("; not recorded: {unrecorded} cases, run before it was")
    } else {
        String::new()
    };
    format!("\nThe analyses simulated at {}{before}.\n", per.join(", "))
}

/// The named effects' first parameter at the run's end (`fitted_at_end`, the model a
/// user gets) beside the step's value the table reads, over the identifiable cases that
/// recorded both; empty when none did.
fn end_line(cases: &[Case]) -> String {
    let both: Vec<&Case> = cases
        .iter()
        .filter(|c| c.identifiable == Some(true) && c.fitted_at_end.is_some())
        .collect();
    if both.is_empty() {
        return String::new();
    }
    let within = |e: Option<f64>| e.is_some_and(|e| e <= 0.25);
    let at_step = both.iter().filter(|c| within(c.magnitude_error())).count();
    let at_end = both
        .iter()
        .filter(|c| within(c.magnitude_error_at_end()))
        .count();
    format!(
        "\nThe named effect's first parameter within 25 % of the truth, on the {} identifiable cases that named and recorded it: {at_step} at the step that named it (the table's figure), {at_end} at the run's end (fitted_model.toml).\n",
        both.len()
    )
}

/// A Bayes factor in a table line.
fn ln_b(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{v:.1}"))
}

/// How the followed advice fared (empty when the study did not follow it): of the cases
/// whose hidden effect was not named first, in how many the workflow recommended an
/// experiment and a record of it then named the hidden effect first.
fn advice_line(cases: &[Case]) -> String {
    let missed: Vec<&Case> = cases
        .iter()
        .filter(|c| !c.hidden.is_empty() && !c.first_correct())
        .collect();
    let advised: Vec<&Case> = missed
        .iter()
        .copied()
        .filter(|c| c.named_after_advice.is_some())
        .collect();
    let failed: Vec<&Case> = missed
        .iter()
        .copied()
        .filter(|c| c.advice_failed.is_some())
        .collect();
    let unadvised: Vec<&Case> = missed
        .iter()
        .copied()
        .filter(|c| c.unadvised.is_some())
        .collect();
    if advised.is_empty() && failed.is_empty() && unadvised.is_empty() {
        return String::new();
    }
    // an effect named first (or decided) that the case hid
    let hidden = |c: &Case, first: Option<&String>| first.is_some_and(|n| c.hidden.contains(n));
    let named = |c: &Case| hidden(c, first(&c.named_after_advice));
    let jointly = |c: &Case| hidden(c, first(&c.named_jointly));
    let decided = |c: &Case| hidden(c, c.decided.as_ref());
    let mut line = format!(
        "\nAdvice followed: {} of the {} cases whose hidden effect was not named first got a \
         recommended experiment the bench recorded ({} more could not be recorded, {} got no \
         recommendation: no design separates their question); a record of \
         it, analysed afresh, named the hidden effect first \
         in {}; analysed with the first record, in {}; the question decided on it (`gap \
         --between`) named it in {}.\n",
        advised.len(),
        missed.len(),
        failed.len(),
        unadvised.len(),
        rate(&advised, named),
        rate(&advised, jointly),
        rate(&advised, decided)
    );
    for c in &failed {
        let _ = writeln!(
            line,
            "- {}: {}: the bench could not record it: {}",
            label(c),
            c.advised.as_deref().unwrap_or("-"),
            c.advice_failed.as_deref().unwrap_or("-")
        );
    }
    for c in &unadvised {
        let _ = writeln!(
            line,
            "- {}: no recommendation: {}",
            label(c),
            c.unadvised.as_deref().unwrap_or("-")
        );
    }
    for c in advised {
        let _ = writeln!(
            line,
            "- {}: {}: afresh {}{}; with the first record {}; between {}: {} (ln B expected {}, found {})",
            label(c),
            c.advised.as_deref().unwrap_or("-"),
            listed(&c.named_after_advice),
            match (c.fitted_after_advice, c.truth) {
                (Some(f), Some(t)) =>
                    format!(" (fitted {:+.1} % off the truth)", 100.0 * (f / t - 1.0)),
                _ => String::new(),
            },
            listed(&c.named_jointly),
            if c.advice_between.is_empty() {
                "-".into()
            } else {
                c.advice_between.join(", ")
            },
            c.decided.as_deref().unwrap_or("nothing"),
            ln_b(c.expected_ln_bayes),
            ln_b(c.found_ln_bayes)
        );
    }
    line
}

/// The first effect a record's analysis named, if it was run and named one.
fn first(named: &Option<Vec<String>>) -> Option<&String> {
    named.as_ref().and_then(|n| n.first())
}

/// What a record's analysis named, in order: "-" when it was not run.
fn listed(named: &Option<Vec<String>>) -> String {
    named.as_ref().map_or("-".into(), |n| {
        if n.is_empty() {
            "nothing".into()
        } else {
            n.join(", ")
        }
    })
}

pub fn write(out: &Path, cases: &[Case]) -> Result<String, String> {
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let md = table(cases);
    std::fs::write(out.join("blind.md"), &md).map_err(|e| e.to_string())?;
    let json = serde_json::to_string_pretty(cases).map_err(|e| e.to_string())?;
    std::fs::write(out.join("blind.json"), json).map_err(|e| e.to_string())?;
    Ok(md)
}

/// A case as the lists name it: what was hidden (or none), the experiment and the bench.
fn label(c: &Case) -> String {
    let hidden = if c.hidden.is_empty() {
        "none".to_string()
    } else {
        c.hidden.join("+")
    };
    format!("{hidden} ({}, {})", c.experiment, c.simulator)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A case as blind.json keeps it, with only the fields every study writes.
    fn case(rtol: Option<f64>) -> Case {
        let mut v = serde_json::json!({
            "hidden": ["payload"], "experiment": "steps", "seed": 1, "named": ["payload"],
            "truth": 3.0, "fitted": 3.1, "initial_gap": 9.0, "remaining_gap": 1.0,
        });
        if let Some(t) = rtol {
            v["rtol"] = t.into();
        }
        serde_json::from_value(v).expect("a case")
    }

    /// A study merged from runs at two tolerances, and from one run before the
    /// tolerance was recorded, says how many cases each had.
    #[test]
    fn a_study_says_the_tolerances_its_analyses_ran_at() {
        assert_eq!(rtol_line(&[case(None)]), "");
        let line = rtol_line(&[
            case(Some(1e-6)),
            case(Some(1e-5)),
            case(Some(1e-5)),
            case(None),
        ]);
        assert_eq!(
            line,
            "\nThe analyses simulated at rtol 1e-6 (1 cases), rtol 1e-5 (2 cases); not recorded: 1 cases, run before it was.\n"
        );
        assert!(table(&[case(Some(1e-6))]).contains("rtol 1e-6 (1 cases)"));
    }

    /// The end's value is counted beside the step's on identifiable cases that recorded
    /// it: a fit the run's later steps brought within 25 % counts at the end only.
    #[test]
    fn a_study_counts_the_fit_at_the_runs_end_beside_the_steps() {
        let at = |end: Option<f64>, identifiable: bool| {
            let mut c = case(None);
            c.fitted = Some(3.9);
            c.fitted_at_end = end;
            c.identifiable = Some(identifiable);
            c
        };
        assert_eq!(end_line(&[at(None, true)]), "");
        let line = end_line(&[
            at(Some(3.1), true),
            at(Some(3.9), true),
            at(Some(3.1), false),
            at(None, true),
        ]);
        assert!(
            line.contains("on the 2 identifiable cases that named and recorded it: 0 at the step that named it (the table's figure), 1 at the run's end"),
            "{line}"
        );
    }
}
