//! The workflow's report: `report.md` for a person (with SVG figures), `report.json` for a
//! machine.

use std::fmt::Write as _;
use std::path::Path;

use serde_json::json;

use super::analysis::describe;
use super::data::{Drive, Experiment, Measured};
use super::effects::{candidate, Kind};
use super::Outcome;
use crate::plot::{stacked_log_x, time_traces, Line, Panel};

fn line(label: &str, t: &[f64], v: &[f64], scale: f64) -> Line {
    Line {
        label: label.into(),
        points: t.iter().zip(v).map(|(t, v)| (*t, v * scale)).collect(),
    }
}

fn figures(out: &Path, o: &Outcome, m: &Measured) -> Result<Vec<String>, String> {
    let mut files = Vec::new();
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
    std::fs::write(out.join("traces.csv"), csv).map_err(|err| err.to_string())?;
    time_traces(&out.join("traces.svg"), "Measured and simulated", &traces)?;
    time_traces(
        &out.join("residuals.svg"),
        "Residuals before and after",
        &residuals,
    )?;
    files.extend(["traces.svg".to_string(), "residuals.svg".to_string()]);
    let pairs = [
        ("y", &o.first.response, &o.last.response),
        (
            "P1-P2",
            &o.first.pressure_response,
            &o.last.pressure_response,
        ),
    ];
    let mut panels = Vec::new();
    let mut csv = String::from("output,frequency_hz,coherent,measured_db,measured_deg,before_db,before_deg,after_db,after_deg\n");
    for (output, r0, r1) in pairs {
        let (Some(r0), Some(r1)) = (r0, r1) else {
            continue;
        };
        let pick = |v: &[f64]| -> Vec<(f64, f64)> {
            r0.freq
                .iter()
                .zip(v)
                .zip(&r0.coherent)
                .filter(|((f, _), ok)| **ok && **f >= 1.0)
                .map(|((f, v), _)| (*f, *v))
                .collect()
        };
        let compared = |title: String, measured: &[f64], before: &[f64], after: &[f64]| Panel {
            title,
            lines: [
                ("measured", measured),
                ("model before", before),
                ("model after", after),
            ]
            .into_iter()
            .map(|(label, v)| Line {
                label: label.into(),
                points: pick(v),
            })
            .collect(),
        };
        panels.push(compared(
            format!("|{output} / input| (dB)"),
            &r0.measured_db,
            &r0.simulated_db,
            &r1.simulated_db,
        ));
        panels.push(compared(
            format!("{output}: phase (deg)"),
            &r0.measured_deg,
            &r0.simulated_deg,
            &r1.simulated_deg,
        ));
        for k in 0..r0.freq.len() {
            let _ = writeln!(
                csv,
                "{output},{},{},{},{},{},{},{},{}",
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
    }
    if !panels.is_empty() {
        std::fs::write(out.join("response.csv"), csv).map_err(|err| err.to_string())?;
        stacked_log_x(
            &out.join("response.svg"),
            "Frequency response estimates (coherent bins; phase unwrapped)",
            "frequency (Hz)",
            &panels,
        )?;
        files.push("response.svg".into());
    }
    Ok(files)
}

pub fn write(out: &Path, o: &Outcome, e: &Experiment, m: &Measured) -> Result<(), String> {
    let figures = figures(out, o, m)?;
    let noise: serde_json::Map<_, _> = o
        .noise
        .iter()
        .map(|(k, v)| (k.to_string(), json!(v)))
        .collect();
    let report = json!({
        "steps": o.steps,
        "initial_gap": o.initial_gap,
        "record_gaps": o.record_gaps,
        "advice": o.advice,
        "remaining_gap": o.remaining_gap,
        "noise_floor": 1.0,
        "noise_floor_gap": super::NOISE_FLOOR_GAP,
        "noise": noise,
        "verdict": o.verdict,
        "localisation_before": o.first,
        "localisation_after": o.last,
        "figures": figures,
    });
    let json_text = serde_json::to_string_pretty(&report).map_err(|err| err.to_string())?;
    std::fs::write(out.join("report.json"), json_text).map_err(|err| err.to_string())?;

    let mut md = String::from("# Model-gap report\n\n");
    let _ = writeln!(
        md,
        "Experiment: mode {}, {}, {} samples at {:.1} ms. Starting model effects: {}.\n",
        e.mode,
        match &e.drive {
            Drive::Proportional { kp, reference } =>
                format!("proportional control u1 = -u2 = {kp} V/m x ({reference} - y)"),
            Drive::OpenLoop => "open loop, the recorded u1 and u2 drive the model".into(),
        },
        m.time.len(),
        m.period() * 1e3,
        list(o.start.effects.active().map(|x| x.name()))
    );
    let _ = writeln!(
        md,
        "The gap is the RMS of measured minus simulated y, P1, P2, each in units of its noise \
         (estimated from the data): 1 is the noise floor.\n\n**Result:** gap {:.2} -> {:.2}: {}.\n",
        o.initial_gap, o.remaining_gap, o.verdict
    );
    md.push_str("## Where the model disagreed with the data\n\n");
    for s in describe(&o.first) {
        let _ = writeln!(md, "- {s}");
    }
    if o.record_gaps.len() > 1 {
        md.push_str("\nRecords fitted jointly (the figures and the localisation are the first's):\n\n| record | gap before | gap after |\n|---|---|---|\n");
        for (i, (a, b)) in o.record_gaps.iter().enumerate() {
            let _ = writeln!(md, "| {} | {a:.2} | {b:.2} |", i + 1);
        }
    }
    for (i, step) in o.steps.iter().enumerate() {
        let what = match step.kind {
            Kind::Add => format!("add `{}`", step.effect),
            Kind::Recalibrate => format!("recalibrate `{}`", step.effect),
        };
        let _ = writeln!(md, "\n## Step {}: {what}\n", i + 1);
        if step.kind == Kind::Add {
            if let Some(c) = hbmodel::Effect::from_name(&step.effect).and_then(candidate) {
                let _ = writeln!(md, "Signature of this effect: {}.\n", c.signature);
            }
        }
        let _ = writeln!(
            md,
            "Fitted: {}. Gap {:.2} -> {:.2}.\n\nEvidence: {}.\n\n\
             Each hypothesis is fitted on half of the samples (alternate {:.0} ms blocks) and \
             judged on the other half; its score is N_eff ln(chi2 before / chi2 after) - k ln N_eff \
             on the judged half, N_eff = {:.0} the effective number of independent residuals \
             (the residual's correlation counted).\n\n\
             | hypothesis | judged gap | score | parameters |\n|---|---|---|---|",
            step.parameters.iter().map(|(k, v)| format!("{k} = {v}")).collect::<Vec<_>>().join(", "),
            step.gap_before,
            step.gap_after,
            step.evidence.statement,
            super::fit::HELD_OUT_BLOCK * 1e3,
            step.evidence.effective_samples,
        );
        for s in &step.candidates {
            let _ = writeln!(
                md,
                "| {} | {:.2} | {:.1} | {} |",
                s.label,
                s.judged_gap,
                s.score,
                s.parameters
                    .iter()
                    .map(|(k, v)| format!("{k} = {v}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        if let Some(a) = &step.advice {
            let _ = writeln!(md, "\nWhat to measure next: {}.\n", a.statement);
            advice_table(&mut md, a);
        }
    }
    if let Some(a) = &o.advice {
        let _ = writeln!(md, "\n## What to measure next\n\n{}.\n", a.statement);
        advice_table(&mut md, a);
    }
    md.push_str("\n## After\n\n");
    for s in describe(&o.last) {
        let _ = writeln!(md, "- {s}");
    }
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

fn advice_table(md: &mut String, a: &super::advice::Advice) {
    md.push_str("| experiment | expected chi-square between them | RMS difference / noise |\n|---|---|---|\n");
    for x in &a.experiments {
        let _ = writeln!(md, "| {} | {:.1} | {:.3} |", x.experiment, x.chi2, x.gap);
    }
    md.push('\n');
}
