//! The workflow's report: `report.md` for a person (with SVG figures), `report.json` for a
//! machine.

use std::fmt::Write as _;
use std::path::Path;

use serde_json::json;

use super::analysis::describe;
use super::data::{Drive, Experiment, Measured};
use super::effects::candidate;
use super::holdout::Validation;
use super::{Outcome, RecordOutcome};
use crate::plot::{stacked_log_x, time_traces, Line, Panel};

fn line(label: &str, t: &[f64], v: &[f64], scale: f64) -> Line {
    Line {
        label: label.into(),
        points: t.iter().zip(v).map(|(t, v)| (*t, v * scale)).collect(),
    }
}

/// Phase points (deg) unwrapped: where two consecutive points jump by more than 180 deg,
/// the rest is moved by whole turns, so that a lag growing through -180 deg (a resonance,
/// a delay) reads as it grows instead of wrapping back to +180.
fn unwrap_phase(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut turns = 0.0;
    let mut out: Vec<(f64, f64)> = Vec::with_capacity(points.len());
    for (k, &(f, deg)) in points.iter().enumerate() {
        if k > 0 {
            let jump = deg + turns - out[k - 1].1;
            turns -= 360.0 * (jump / 360.0).round();
        }
        out.push((f, deg + turns));
    }
    out
}

/// The files a record's figures go to: plain names for a single record, prefixed by the
/// record's name when there are several.
fn prefix(names: &[&str], name: &str) -> String {
    if names.len() > 1 {
        format!("{name}-")
    } else {
        String::new()
    }
}

/// Every file the report writes for records `names` (checked against the inputs before
/// anything is written: a user's file is never overwritten).
pub fn outputs(names: &[&str]) -> Vec<String> {
    let mut files: Vec<String> = [
        "fitted_model.toml",
        "report.json",
        "report.md",
        super::advice::QUESTION_MODEL,
    ]
    .map(String::from)
    .to_vec();
    for name in names {
        let p = prefix(names, name);
        for f in FIGURE_FILES {
            files.push(format!("{p}{f}"));
        }
    }
    files
}

const FIGURE_FILES: [&str; 5] = [
    "traces.csv",
    "traces.svg",
    "residuals.svg",
    "response.csv",
    "response.svg",
];

fn figures(out: &Path, o: &RecordOutcome, p: &str) -> Result<Vec<String>, String> {
    let mut files = Vec::new();
    let m = &o.measured;
    let t = &m.time;
    let mut traces = Vec::new();
    let mut residuals = Vec::new();
    for (name, _) in &o.noise {
        let (unit, scale) = if *name == "y" {
            ("mm", 1e3)
        } else {
            ("bar", 1e-5)
        };
        let (Some(meas), Some(b), Some(a)) = (m.get(name), o.before.get(name), o.after.get(name))
        else {
            continue;
        };
        traces.push(Panel {
            title: format!("{name} ({unit})"),
            lines: vec![
                line("measured", t, meas, scale),
                line("model before", t, b, scale),
                line("model after", t, a, scale),
            ],
        });
        let diff = |s: &[f64]| meas.iter().zip(s).map(|(m, s)| m - s).collect::<Vec<_>>();
        residuals.push(Panel {
            title: format!("{name}: measured - model ({unit})"),
            lines: vec![
                line("before", t, &diff(b), scale),
                line("after", t, &diff(a), scale),
            ],
        });
    }
    let mut csv = String::from("time");
    let names: Vec<&str> = o.noise.iter().map(|(n, _)| *n).collect();
    for n in &names {
        let _ = write!(csv, ",{n}_measured,{n}_before,{n}_after");
    }
    csv.push('\n');
    for (k, tk) in t.iter().enumerate() {
        let _ = write!(csv, "{tk:.6}");
        for n in &names {
            for s in [m.get(n), o.before.get(n), o.after.get(n)] {
                let _ = write!(csv, ",{:e}", s.map_or(f64::NAN, |v| v[k]));
            }
        }
        csv.push('\n');
    }
    std::fs::write(out.join(format!("{p}traces.csv")), csv).map_err(|err| err.to_string())?;
    time_traces(
        &out.join(format!("{p}traces.svg")),
        &format!("Measured and simulated: {}", o.name),
        &traces,
    )?;
    time_traces(
        &out.join(format!("{p}residuals.svg")),
        &format!("Residuals before and after: {}", o.name),
        &residuals,
    )?;
    files.extend([format!("{p}traces.svg"), format!("{p}residuals.svg")]);
    if let (Some(r0), Some(r1)) = (&o.first.response, &o.last.response) {
        let pick = |v: &[f64]| -> Vec<(f64, f64)> {
            r0.freq
                .iter()
                .zip(v)
                .zip(&r0.coherent)
                .filter(|((f, _), ok)| **ok && **f >= 1.0)
                .map(|((f, v), _)| (*f, *v))
                .collect()
        };
        let compared = |title: &str, lines: [&[f64]; 3], phase: bool| Panel {
            title: title.into(),
            lines: ["measured", "model before", "model after"]
                .into_iter()
                .zip(lines)
                .map(|(label, v)| Line {
                    label: label.into(),
                    points: if phase {
                        unwrap_phase(&pick(v))
                    } else {
                        pick(v)
                    },
                })
                .collect(),
        };
        let panels = [
            compared(
                "|y / input| (dB)",
                [&r0.measured_db, &r0.simulated_db, &r1.simulated_db],
                false,
            ),
            compared(
                "phase (deg, unwrapped)",
                [&r0.measured_deg, &r0.simulated_deg, &r1.simulated_deg],
                true,
            ),
        ];
        let mut csv = String::from(
            "frequency_hz,coherent,measured_db,measured_deg,before_db,before_deg,after_db,after_deg\n",
        );
        for k in 0..r0.freq.len() {
            let _ = writeln!(
                csv,
                "{},{},{},{},{},{},{},{}",
                r0.freq[k],
                r0.coherent[k],
                r0.measured_db[k],
                r0.measured_deg[k],
                r0.simulated_db[k],
                r0.simulated_deg[k],
                r1.simulated_db[k],
                r1.simulated_deg[k]
            );
        }
        std::fs::write(out.join(format!("{p}response.csv")), csv).map_err(|err| err.to_string())?;
        stacked_log_x(
            &out.join(format!("{p}response.svg")),
            &format!("Frequency response estimates (coherent bins): {}", o.name),
            "frequency (Hz)",
            &panels,
        )?;
        files.push(format!("{p}response.svg"));
    }
    Ok(files)
}

/// How a record's bench was driven, in words.
fn drive(e: &Experiment, m: &Measured) -> String {
    format!(
        "mode {}, {}, {} samples at {:.1} ms",
        e.mode,
        match &e.drive {
            Drive::Proportional { kp, reference } =>
                format!("proportional control u1 = -u2 = {kp} V/m x ({reference} - y)"),
            Drive::OpenLoop => "open loop, the recorded u1 and u2 drive the model".into(),
        },
        m.time.len(),
        m.period() * 1e3,
    )
}

fn noise_json(noise: &[(&'static str, f64)]) -> serde_json::Map<String, serde_json::Value> {
    noise
        .iter()
        .map(|(k, v)| (k.to_string(), json!(v)))
        .collect()
}

/// What the user said the starting model was: a parameter file, or nothing (the built-in
/// parameters with every effect off).
///
/// A run handed its model in code (`hbench blind`'s known model, section 4.4's with form
/// error) has no file and is no default model either: its effects are on. Until session
/// 48 every blind case's report said "every effect off" above the list of the two it
/// had on.
pub fn start_note(model: Option<&Path>, start: &hbmodel::Params) -> String {
    match model {
        Some(f) => format!("the parameter file `{}`", f.display()),
        None if start.effects.active().next().is_some() => {
            "the built-in parameters with the effects listed on, handed over without a file \
             (`hbench blind`'s known model: never the structure of the bench that made the \
             record)"
                .into()
        }
        None => "the built-in parameters with every effect off (no `--model`). **The first \
                 effects named from it are often what every bench has, friction and leakage, \
                 not what this bench lacks** (issue 14: from the default model a hidden \
                 manifold came third, after the valve's lag and viscous friction): give the \
                 model you know with `--model`"
            .into(),
    }
}

/// `report.md`, `report.json`, the question's model and the figures into `out`, for a run
/// started from `model` (None: the built-in parameters).
pub fn write(out: &Path, o: &Outcome, model: Option<&Path>) -> Result<(), String> {
    let names: Vec<&str> = o.records.iter().map(|r| r.name.as_str()).collect();
    let mut figures = Vec::new();
    for r in &o.records {
        figures.extend(self::figures(out, r, &prefix(&names, &r.name))?);
    }
    let records: Vec<serde_json::Value> = o
        .records
        .iter()
        .map(|r| {
            json!({
                "name": r.name,
                "samples": r.measured.time.len(),
                "noise": noise_json(&r.noise),
                "initial_gap": r.initial_gap,
                "remaining_gap": r.remaining_gap,
                "localisation_before": r.first,
                "localisation_after": r.last,
            })
        })
        .collect();
    let mut report = json!({
        "steps": o.steps,
        "initial_gap": o.initial_gap,
        "remaining_gap": o.remaining_gap,
        "effective_samples": o.effective_samples,
        "samples": o.samples,
        "rejected": o.rejected,
        "noise_floor": 1.0,
        "rtol": o.start.solver.rtol,
        "noise_floor_gap": super::NOISE_FLOOR_GAP,
        "records": records,
        "verdict": o.verdict,
        "figures": figures,
        "advice": o.advice,
        "refused_on_held_out_data": o.refusals,
        "revision": o.revision,
        "timing": o.timing,
        "start_model": model.map(|m| m.display().to_string()),
    });
    // a single record keeps the fields of one-record reports at the top level
    if let [r] = o.records.as_slice() {
        report["noise"] = json!(noise_json(&r.noise));
        report["localisation_before"] = json!(r.first);
        report["localisation_after"] = json!(r.last);
    }
    let json_text = serde_json::to_string_pretty(&report).map_err(|err| err.to_string())?;
    std::fs::write(out.join("report.json"), json_text).map_err(|err| err.to_string())?;
    let path = out.join(super::advice::QUESTION_MODEL);
    if let Some(a) = &o.advice {
        // what `hbench gap --between` fits the question's candidates from
        std::fs::write(&path, a.from.to_toml())
            .map_err(|err| format!("cannot write {}: {err}", path.display()))?;
    } else if path.is_file() {
        // an earlier run's question, left beside a report that asks none, would be taken
        // for this one's (the file is among `outputs`, checked to be no input)
        std::fs::remove_file(&path)
            .map_err(|err| format!("cannot remove {}: {err}", path.display()))?;
        println!(
            "removed {}: an earlier run's question, and this report asks none",
            path.display()
        );
    }

    let mut md = String::from("# Model-gap report\n\n");
    for r in &o.records {
        let _ = writeln!(
            md,
            "Record `{}`: {}; gap {:.2} -> {:.2}.",
            r.name,
            drive(&r.experiment, &r.measured),
            r.initial_gap,
            r.remaining_gap
        );
    }
    if o.records.len() > 1 {
        md.push_str(
            "\nThe records are fitted jointly: every step is judged on all of them at once. \
             Each record's residual variance is its own (a model is never equally far from \
             two experiments): a fit weighs each record by its misfit under the model before \
             it, and a candidate's score sums each record's relative drop in that record's \
             own independent samples. The gaps are in each record's noise.\n",
        );
    }
    let _ = writeln!(
        md,
        "\nStarting model: {}; effects on: {}.\n",
        start_note(model, &o.start),
        list(o.start.effects.active().map(|x| x.name()))
    );
    let _ = writeln!(
        md,
        "The gap is the RMS of measured minus simulated y, P1, P2, each in units of its noise \
         (estimated from the data): 1 is the noise floor.\n\n**Result:** gap {:.2} -> {:.2}: {}.\n",
        o.initial_gap, o.remaining_gap, o.verdict
    );
    if o.steps.iter().any(|s| !s.spread.is_empty()) {
        let _ = writeln!(
            md,
            "Each fitted parameter is given with its standard error (1 s.e.): how far the \
             record's noise lets it move. It says nothing of the bias a model-form error puts \
             into a fit: on blind records with form error the fits lay 1 to 174 standard \
             errors from the truth (docs/gap.md).\n"
        );
    }
    for r in &o.records {
        let _ = writeln!(md, "## Where the model disagreed with `{}`\n", r.name);
        for s in describe(&r.first) {
            let _ = writeln!(md, "- {s}");
        }
        md.push('\n');
    }
    for (i, step) in o.steps.iter().enumerate() {
        let with = if step.brings.is_empty() {
            String::new()
        } else {
            format!(
                " (with `{}`, which it requires, at built-in size)",
                step.brings.join("`, `")
            )
        };
        let verb = match step.kind {
            super::effects::StepKind::Add => "add",
            super::effects::StepKind::Recalibrate => "recalibrate",
        };
        let _ = writeln!(md, "\n## Step {}: {verb} `{}`{with}\n", i + 1, step.name);
        if let Some(c) = hbmodel::Effect::from_name(&step.name).and_then(candidate) {
            let _ = writeln!(md, "Signature of this effect: {}.\n", c.signature);
        }
        let n = o.samples as f64;
        let _ = writeln!(
            md,
            "The residual before this step was worth {:.0} independent samples of its {n:.0} \
             (correlation time {:.1} samples): scores count the chi-square drop per \
             independent sample.",
            step.effective_samples,
            n / step.effective_samples.max(1.0)
        );
        if let Some(p) = &step.preference {
            let _ = writeln!(md, "{}\n", p.line(&step.name));
        }
        let _ = writeln!(
            md,
            "{}Fitted: {}. Gap {:.2} -> {:.2}.",
            step.validation
                .as_ref()
                .map_or(String::new(), Validation::describe),
            fitted_values(step),
            step.gap_before,
            step.gap_after
        );
        if !step.signals.is_empty() {
            let _ = writeln!(
                md,
                "\n{}",
                super::signals::describe(&step.signals, &step.name)
            );
        }
        // a step the run's revision re-fitted before asking again had no candidates
        if !step.candidates.is_empty() {
            let _ = writeln!(
                md,
                "\n| candidate | gap after fit | score (N_eff ln(chi2 / chi2') - k ln N_eff, k the parameters it adds; an added effect needs over {:.0}) | parameters |\n|---|---|---|---|",
                2.0 * super::evidence::ADD_LN_BAYES
            );
        }
        let mut c = step.candidates.clone();
        c.sort_by(|a, b| b.score.total_cmp(&a.score));
        for s in c {
            let _ = writeln!(
                md,
                "| {} | {:.2} | {:.0}{} | {} |",
                s.effect,
                s.gap,
                s.score,
                s.on_bound
                    .map(|(p, v)| format!(" (not taken: {p} = {v} on a bound of its fit)"))
                    .or_else(|| s.trades.as_ref().map(|t| format!(
                        " (took {t} further from the data while it brought the others closer)"
                    )))
                    .unwrap_or_default(),
                s.parameters
                    .iter()
                    .map(|(k, v)| format!("{k} = {v}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
    }
    for r in &o.records {
        let _ = writeln!(md, "\n## After, on `{}`\n", r.name);
        for s in describe(&r.last) {
            let _ = writeln!(md, "- {s}");
        }
    }
    if let Some(r) = &o.revision {
        let _ = writeln!(md, "\n## Step {} asked again\n\n{}.", r.step + 1, r.verdict);
        for v in &r.others {
            let _ = writeln!(md, "\nAlso asked: {v}.");
        }
    }
    if !o.refusals.is_empty() {
        md.push_str("\n## Refused after winning a round\n\n");
        for v in &o.refusals {
            let _ = writeln!(
                md,
                "- `{}`, {}: {}",
                v.effect,
                v.why_refused(),
                v.describe()
            );
        }
    }
    if let Some(a) = &o.advice {
        md.push_str(&super::advice::markdown(a));
    }
    md.push('\n');
    md.push_str(&super::budget::markdown(&o.timing));
    md.push_str("\n## Figures\n\n");
    for f in &figures {
        let _ = writeln!(md, "![{f}]({f})\n");
    }
    md.push_str("The fitted parameter file is `fitted_model.toml`.\n");
    std::fs::write(out.join("report.md"), md).map_err(|err| err.to_string())
}

fn list<'a>(names: impl Iterator<Item = &'a str>) -> String {
    let v: Vec<_> = names.collect();
    if v.is_empty() {
        "none (the control model (II.1))".into()
    } else {
        v.join(", ")
    }
}

/// A step's fitted parameters, each with its standard error and the parameter it is
/// most correlated with when the correlation is strong (`fit::spread`).
fn fitted_values(step: &super::Step) -> String {
    if step.spread.is_empty() {
        return step
            .parameters
            .iter()
            .map(|(k, v)| format!("{k} = {v}"))
            .collect::<Vec<_>>()
            .join(", ");
    }
    step.spread
        .iter()
        .map(|s| {
            let std = s
                .std
                .map_or(" (not pinned by the record)".to_string(), |d| {
                    format!(" +- {d:.3e} (1 s.e.)")
                });
            // a correlation this strong means the record trades the two
            let with = s
                .most_correlated
                .filter(|c| c.r.abs() >= STRONG_CORRELATION)
                .map_or(String::new(), |c| {
                    format!(", correlated {:.2} with {}", c.r, c.with)
                });
            format!("{} = {:.4e}{std}{with}", s.path, s.value)
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// A correlation between two fitted parameters above which the report names the pair:
/// at 0.8 the standard error of either is 1.7 times what it would be with the other
/// fixed (1 / sqrt(1 - r^2)). The Coulomb and viscous friction fitted together on +-10 mm
/// steps are correlated -0.81 (measured, test in `fit`).
const STRONG_CORRELATION: f64 = 0.8;

#[cfg(test)]
mod tests {
    use super::{start_note, unwrap_phase};

    /// The report says where the run started as it did: a file, the built-in parameters
    /// with every effect off, or a model handed over in code with effects on (a blind
    /// case's section 4.4 model, whose reports said "every effect off" until session 48).
    #[test]
    fn the_starting_model_is_named_as_it_was() {
        let default = hbmodel::Params::default();
        assert!(start_note(None, &default).contains("every effect off"));
        let known = crate::gap::variants::section_4_4();
        let note = start_note(None, &known);
        assert!(!note.contains("every effect off"), "{note}");
        assert!(note.contains("effects listed on"), "{note}");
        let file = std::path::Path::new("bench.toml");
        assert!(start_note(Some(file), &known).contains("`bench.toml`"));
    }

    #[test]
    fn phase_is_unwrapped_through_minus_180() {
        // a lag growing by 50 deg a point, wrapped into (-180, 180]
        let wrapped: Vec<(f64, f64)> = (0..12)
            .map(|k| {
                let deg = -50.0 * k as f64;
                (k as f64, (deg + 180.0f64).rem_euclid(360.0) - 180.0)
            })
            .collect();
        for (k, (_, deg)) in unwrap_phase(&wrapped).iter().enumerate() {
            assert!((deg + 50.0 * k as f64).abs() < 1e-9, "{k}: {deg}");
        }
    }
}
