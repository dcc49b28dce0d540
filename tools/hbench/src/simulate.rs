//! `hbench simulate`: run one of the thesis's closed-loop experiments on the full bench
//! model and write, per run, the time traces as CSV; per experiment, an SVG figure
//! (position and error, chamber pressures, commands) and a JSON file of the metrics.
//! With `--inputs-only` it writes instead the input table and start values that make
//! `bench_closed_loop.fmu` run the same experiment under any FMI master.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use hbmodel::control::config::LawKind;
use hbmodel::control::scenario::{self, law_name, Overrides, Run, Scenario, CATALOGUE};
use hbmodel::control::Sample;
use hbmodel::effects::EFFECTS;
use hbmodel::params::PARAMS;
use hbmodel::{Mode, Params};
use serde_json::{json, Value};

use crate::plot::{time_traces, Line, Panel};

/// What the user asked for on the command line.
pub struct Request {
    pub scenario: String,
    pub out: PathBuf,
    pub parameters: Option<PathBuf>,
    pub overrides: Overrides,
    pub inputs_only: bool,
}

pub fn parse_law(s: &str) -> Result<LawKind, String> {
    LawKind::ALL
        .into_iter()
        .find(|&l| law_name(l) == s)
        .ok_or_else(|| {
            let names: Vec<_> = LawKind::ALL.into_iter().map(law_name).collect();
            format!("unknown law '{s}'; known: {}", names.join(", "))
        })
}

pub fn parse_mode(s: &str) -> Result<Mode, String> {
    s.parse::<u8>()
        .ok()
        .and_then(|m| Mode::try_from(m).ok())
        .ok_or_else(|| format!("mode must be 1, 2 or 3, not '{s}'"))
}

pub fn parse_gains(s: &str) -> Result<bool, String> {
    match s {
        "low" => Ok(false),
        "high" => Ok(true),
        _ => Err(format!("gains must be 'low' or 'high', not '{s}'")),
    }
}

pub fn parse_dao2(s: &str) -> Result<[f64; 2], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("DAO2 gains are 'Kd0,Kd1' in 1/s, not '{s}'"))?;
    match v[..] {
        [a, b] if a > 0.0 && b > 0.0 => Ok([a, b]),
        _ => Err(format!(
            "DAO2 gains are two positive numbers 'Kd0,Kd1', not '{s}'"
        )),
    }
}

pub fn list() -> String {
    let mut s = String::from("scenarios (hbench simulate --scenario NAME):\n");
    for c in CATALOGUE {
        let _ = writeln!(s, "  {:<9} {}", c.name, c.description);
    }
    s
}

pub fn main(req: &Request) -> Result<(), String> {
    let base = match &req.parameters {
        Some(f) => Params::load(f).map_err(|e| e.to_string())?,
        None => Params::thesis_bench(Mode::ThreeWay),
    };
    let runs = scenario::build(&req.scenario, &base, &req.overrides)?;
    std::fs::create_dir_all(&req.out)
        .map_err(|e| format!("cannot create {}: {e}", req.out.display()))?;
    if req.inputs_only {
        return write_inputs(req, &runs);
    }
    let results = run_all(&runs)?;
    let mut summary = Vec::new();
    for (s, r) in runs.iter().zip(&results) {
        let path = req.out.join(format!("{}.csv", s.label));
        write_file(&path, &trace_csv(s, &r.trace))?;
        summary.push(json!({
            "label": s.label,
            "mode": s.params.mode.number(),
            "law": law_name(s.controller.law),
            "payload_kg": if s.params.has(hbmodel::Effect::Payload) { s.params.actuator.payload_mass } else { 0.0 },
            "dao2": s.controller.dao2,
            "csv": path.file_name().map(|f| f.to_string_lossy().into_owned()),
            "metrics": r.metrics,
            "windows": s.windows,
        }));
    }
    let svg = req.out.join(format!("{}.svg", req.scenario));
    plot(&svg, &req.scenario, &runs, &results)?;
    let report = json!({"scenario": req.scenario, "runs": summary});
    let json_path = req.out.join(format!("{}.json", req.scenario));
    write_file(
        &json_path,
        &serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?,
    )?;
    println!("{}", table(&runs, &results));
    println!(
        "wrote {} CSV file(s), {} and {}",
        runs.len(),
        svg.display(),
        json_path.display()
    );
    Ok(())
}

/// Runs in parallel on all cores, with a progress bar.
pub fn run_all(runs: &[Scenario]) -> Result<Vec<Run>, String> {
    let bar = crate::parallel::bar(runs.len(), "runs", true);
    crate::parallel::map(runs, &bar, |s| s.label.clone(), Scenario::run)
        .into_iter()
        .collect()
}

fn write_file(path: &Path, text: &str) -> Result<(), String> {
    std::fs::write(path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

const TRACE_HEADER: &str = "time,y_ref,y,error,v,P1,P2,P_ref,u1,u2,Q_supply,x_s1,x_s2";

fn trace_csv(s: &Scenario, trace: &[Sample]) -> String {
    let mut csv = format!("{TRACE_HEADER}\n");
    for k in trace {
        let o = &k.out;
        let _ = writeln!(
            csv,
            "{:.6},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e}",
            k.t,
            k.reference,
            o.y,
            o.y - k.reference,
            o.v,
            o.p1,
            o.p2,
            s.p_ref,
            k.inputs.u1,
            k.inputs.u2,
            o.q_supply,
            o.x_s1,
            o.x_s2
        );
    }
    csv
}

fn plot(path: &Path, name: &str, runs: &[Scenario], results: &[Run]) -> Result<(), String> {
    let series = |f: &dyn Fn(&Sample) -> f64| -> Vec<Vec<(f64, f64)>> {
        results
            .iter()
            .map(|r| r.trace.iter().map(|s| (s.t, f(s))).collect())
            .collect()
    };
    let panel = |title: &str, data: Vec<Vec<(f64, f64)>>, labels: &dyn Fn(usize) -> String| Panel {
        title: title.into(),
        lines: data
            .into_iter()
            .enumerate()
            .map(|(k, points)| Line {
                label: labels(k),
                points,
            })
            .collect(),
    };
    let label = |k: usize| runs[k].label.clone();
    let mut position = panel("position y (mm)", series(&|s| s.out.y * 1e3), &label);
    let first = &results[0].trace;
    position.lines.push(Line {
        label: "reference".into(),
        points: first.iter().map(|s| (s.t, s.reference * 1e3)).collect(),
    });
    let panels = vec![
        position,
        panel(
            "error y - y_ref (um)",
            series(&|s| (s.out.y - s.reference) * 1e6),
            &label,
        ),
        panel("P1 (bar)", series(&|s| s.out.p1 / 1e5), &|k| {
            format!("{} P1", runs[k].label)
        }),
        panel("P2 (bar)", series(&|s| s.out.p2 / 1e5), &|k| {
            format!("{} P2", runs[k].label)
        }),
        panel("u1 (V)", series(&|s| s.inputs.u1), &label),
    ];
    time_traces(path, &format!("hbench simulate --scenario {name}"), &panels)
}

fn table(runs: &[Scenario], results: &[Run]) -> String {
    let mut s = String::from(
        "| run | max transient (um) | transient STD (um) | static mean (um) | static STD (um) | peak P (bar) | supply energy (J) | pressure tracking max (bar) | |u| max (V) |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for (sc, r) in runs.iter().zip(results) {
        let m = &r.metrics;
        let _ = writeln!(
            s,
            "| {} | {:.0} | {:.0} | {:.1} | {:.1} | {:.1} | {:.0} | {} | {:.2} |",
            sc.label,
            m.transient_max * 1e6,
            m.transient_std * 1e6,
            m.static_mean * 1e6,
            m.static_std * 1e6,
            m.peak_pressure / 1e5,
            m.supply_energy,
            m.pressure_error_max
                .map_or("-".into(), |p| format!("{:.2}", p / 1e5)),
            m.command_max
        );
    }
    s
}

/// The FMU parameters that make `bench_closed_loop.fmu` run scenario `s`: every effect
/// switch and registry parameter of the bench (so the FMU's own defaults do not matter),
/// the mode, and the law with its gains.
fn start_values(s: &Scenario) -> Value {
    let mut v = serde_json::Map::new();
    let p = &s.params;
    let mut params = p.clone();
    params.initial_position = s.signal.at(0.0)[0];
    for spec in PARAMS {
        v.insert(
            hbfmu::models::fmu_name(spec.path).into(),
            json!(spec.get(&params)),
        );
    }
    for e in EFFECTS {
        v.insert(format!("effect.{}", e.name), json!(p.has(e.effect)));
    }
    let c = &s.controller;
    for (name, value) in [
        ("mode", json!(p.mode.number())),
        ("law", json!(hbfmu::models::controller::law_code(c.law))),
        ("Kp", json!(c.kp)),
        ("c1", json!(c.c[0])),
        ("c2", json!(c.c[1])),
        ("c3", json!(c.c[2])),
        ("c4", json!(c.c[3])),
        ("lambda", json!(c.lambda)),
        ("Kp_model_free", json!(c.kp_model_free)),
        ("Kd0", json!(c.dao2[0])),
        ("Kd1", json!(c.dao2[1])),
        // the input table carries the trajectory's exact derivatives
        ("reference_derivatives", json!(true)),
    ] {
        v.insert(name.into(), value);
    }
    Value::Object(v)
}

fn write_inputs(req: &Request, runs: &[Scenario]) -> Result<(), String> {
    let [s] = runs else {
        let labels: Vec<_> = runs.iter().map(|r| r.label.as_str()).collect();
        return Err(format!(
            "--inputs-only needs a single run, and '{}' has {} ({}); use 'moves', 'steps' or \
             'sine' with --law/--payload/--dao2/--mode to pick one",
            req.scenario,
            runs.len(),
            labels.join(", ")
        ));
    };
    let period = s.controller.period;
    let n = (s.duration / period).round() as usize;
    let mut csv = String::from("time,y_ref,dy_ref,d2y_ref,d3y_ref,P_ref,F_ext\n");
    for k in 0..=n {
        let t = k as f64 * period;
        let [y, dy, d2y, d3y] = s.signal.at(t);
        let _ = writeln!(csv, "{t:.6},{y:e},{dy:e},{d2y:e},{d3y:e},{:e},0", s.p_ref);
    }
    write_file(&req.out.join("inputs.csv"), &csv)?;
    let description = CATALOGUE
        .iter()
        .find(|c| c.name == req.scenario)
        .map_or("", |c| c.description);
    let doc = json!({
        "name": req.scenario,
        "label": s.label,
        "description": description,
        "fmu": "bench_closed_loop.fmu",
        "stop_time": s.duration,
        "communication_step": period,
        "inputs": "inputs.csv",
        "start_values": start_values(s),
        "windows": s.windows,
    });
    write_file(
        &req.out.join("scenario.json"),
        &serde_json::to_string_pretty(&doc).map_err(|e| e.to_string())?,
    )?;
    println!(
        "wrote {0}/inputs.csv and {0}/scenario.json ({1}, {2} s)",
        req.out.display(),
        s.label,
        s.duration
    );
    Ok(())
}
