//! The model-gap workflow's inputs: `experiment.toml` (how the bench was driven) and
//! `measured.csv` (what it recorded), read with errors that name the file, the line or
//! row, and the field or column.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use hbmodel::{Mode, Params};
use serde::{Deserialize, Serialize};

/// How the commands of the experiment were produced.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Drive {
    /// u1 = -u2 = kp (reference - y), sampled every `period`, saturated at +-10 V.
    Proportional {
        kp: f64,
        /// Column holding the position reference.
        reference: String,
    },
    /// The u1/u2 columns drive the model directly (held between samples).
    OpenLoop,
}

/// `experiment.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Experiment {
    pub mode: u8,
    pub supply_pressure: f64,
    pub tank_pressure: f64,
    pub initial_position: f64,
    pub drive: Drive,
}

impl Experiment {
    /// The bench operating point this experiment fixes on top of a model's parameters.
    pub fn apply(&self, p: &mut Params) {
        p.mode = Mode::try_from(self.mode).unwrap_or(p.mode);
        p.supply_pressure = self.supply_pressure;
        p.tank_pressure = self.tank_pressure;
        p.initial_position = self.initial_position;
    }

    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("an experiment serialises")
    }
}

/// Physical ranges the measured columns must lie in (SI), with the reason.
fn column_range(name: &str) -> Option<(f64, f64)> {
    match name {
        // the LVDT spans +-0.15 m about mid stroke (Table 1.1)
        "y" | "y_ref" => Some((-0.15, 0.15)),
        // absolute pressures: none below vacuum; the sensors read up to 206 bar, the
        // supply can reach 350 bar
        "P1" | "P2" | "P_A1" | "P_B1" | "P_A2" | "P_B2" => Some((0.0, 400e5)),
        // servovalve commands are +-10 V rated
        "u1" | "u2" => Some((-10.5, 10.5)),
        "v" => Some((-5.0, 5.0)),
        _ => None,
    }
}

/// Columns `measured.csv` may hold: bench.fmu's inputs and outputs, and references.
pub const KNOWN_COLUMNS: [&str; 11] = [
    "u1", "u2", "y", "v", "P1", "P2", "P_A1", "P_B1", "P_A2", "P_B2", "y_ref",
];

/// Signals the workflow compares with the model when present.
pub const COMPARED: [&str; 3] = ["y", "P1", "P2"];

/// `measured.csv`: a time base and named columns, SI units.
#[derive(Debug, Clone, PartialEq)]
pub struct Measured {
    pub time: Vec<f64>,
    pub columns: BTreeMap<String, Vec<f64>>,
}

impl Measured {
    pub fn get(&self, name: &str) -> Option<&[f64]> {
        self.columns.get(name).map(Vec::as_slice)
    }

    /// Time the record spans (s), first sample to last; 0 for an empty record.
    pub fn duration(&self) -> f64 {
        match (self.time.first(), self.time.last()) {
            (Some(t0), Some(t1)) => t1 - t0,
            _ => 0.0,
        }
    }

    /// Sampling period (s), from the first interval.
    pub fn period(&self) -> f64 {
        self.time[1] - self.time[0]
    }

    pub fn to_csv(&self) -> String {
        let names: Vec<&String> = self.columns.keys().collect();
        let mut s = String::from("time");
        for n in &names {
            s.push(',');
            s.push_str(n);
        }
        s.push('\n');
        for (k, t) in self.time.iter().enumerate() {
            let _ = write!(s, "{t:.6}");
            for n in &names {
                let _ = write!(s, ",{:e}", self.columns[*n][k]);
            }
            s.push('\n');
        }
        s
    }
}

fn read(path: &Path) -> Result<String, String> {
    std::fs::read_to_string(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))
}

pub fn load_experiment(path: &Path) -> Result<Experiment, String> {
    let text = read(path)?;
    let e: Experiment = toml::from_str(&text).map_err(|err| {
        let line = err
            .span()
            .map(|s| text[..s.start].lines().count().max(1))
            .map_or(String::new(), |l| format!(":{l}"));
        format!("{}{line}: {}", path.display(), err.message())
    })?;
    let field_line = |field: &str| {
        text.lines()
            .position(|l| l.trim_start().starts_with(field))
            .map_or(String::new(), |i| format!(":{}", i + 1))
    };
    let bad = |field: &str, why: String| {
        format!(
            "{}{}: field `{field}`: {why}",
            path.display(),
            field_line(field)
        )
    };
    if Mode::try_from(e.mode).is_err() {
        return Err(bad(
            "mode",
            format!("{} is not a working mode (1, 2 or 3)", e.mode),
        ));
    }
    for (field, v) in [
        ("supply_pressure", e.supply_pressure),
        ("tank_pressure", e.tank_pressure),
        ("initial_position", e.initial_position),
    ] {
        let spec = hbmodel::params::param(field).expect("registered");
        if !(v.is_finite() && v >= spec.min && v <= spec.max) {
            return Err(bad(
                field,
                format!("{v} {} outside [{}, {}]", spec.unit, spec.min, spec.max),
            ));
        }
    }
    if e.tank_pressure >= e.supply_pressure {
        return Err(bad("tank_pressure", "must be below supply_pressure".into()));
    }
    if let Drive::Proportional { kp, .. } = &e.drive {
        if !(kp.is_finite() && *kp > 0.0) {
            return Err(bad("kp", format!("{kp} V/m must be a positive gain")));
        }
    }
    Ok(e)
}

/// Read `measured.csv` and check it against the experiment: the columns the drive needs
/// are there, nothing unknown, every value finite and in physical range, time strictly
/// increasing and evenly sampled.
pub fn load_measured(path: &Path, e: &Experiment) -> Result<Measured, String> {
    let text = read(path)?;
    let file = path.display();
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines
        .next()
        .ok_or(format!("{file}: empty file, expected a header line"))?;
    let names: Vec<String> = header.split(',').map(|s| s.trim().to_string()).collect();
    if names.first().map(String::as_str) != Some("time") {
        return Err(format!(
            "{file}:1: the first column must be `time`, not `{}`",
            names[0]
        ));
    }
    for (i, n) in names.iter().enumerate().skip(1) {
        if !KNOWN_COLUMNS.contains(&n.as_str()) {
            return Err(format!(
                "{file}:1: column {} `{n}` is not a bench.fmu variable nor a reference (known: {})",
                i + 1,
                KNOWN_COLUMNS.join(", ")
            ));
        }
        if names[..i].contains(n) {
            return Err(format!("{file}:1: column `{n}` appears twice"));
        }
    }
    let mut needed: Vec<&str> = vec!["y"];
    match &e.drive {
        Drive::Proportional { reference, .. } => needed.push(reference),
        Drive::OpenLoop => needed.extend(["u1", "u2"]),
    }
    for n in needed {
        if !names.iter().any(|c| c == n) {
            return Err(format!(
                "{file}:1: missing column `{n}`, which the {:?} drive needs",
                e.drive
            ));
        }
    }
    let mut time = Vec::new();
    let mut columns: BTreeMap<String, Vec<f64>> =
        names[1..].iter().map(|n| (n.clone(), Vec::new())).collect();
    for (i, line) in lines {
        let row = i + 1;
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        if cells.len() != names.len() {
            return Err(format!(
                "{file}:{row}: {} values for {} columns",
                cells.len(),
                names.len()
            ));
        }
        for (c, cell) in cells.iter().enumerate() {
            let name = &names[c];
            let v: f64 = cell
                .parse()
                .map_err(|_| format!("{file}:{row}: column `{name}`: `{cell}` is not a number"))?;
            if !v.is_finite() {
                return Err(format!(
                    "{file}:{row}: column `{name}`: {cell} is not finite"
                ));
            }
            if let Some((lo, hi)) = column_range(name) {
                if v < lo || v > hi {
                    return Err(format!(
                        "{file}:{row}: column `{name}`: {v} outside the physical range [{lo}, {hi}] (SI units)"
                    ));
                }
            }
            if c == 0 {
                if let Some(&last) = time.last() {
                    if v <= last {
                        return Err(format!(
                            "{file}:{row}: column `time`: {v} s does not increase (previous {last} s)"
                        ));
                    }
                }
                time.push(v);
            } else if let Some(col) = columns.get_mut(name) {
                col.push(v);
            }
        }
    }
    if time.len() < 16 {
        return Err(format!("{file}: {} samples, need at least 16", time.len()));
    }
    let period = time[1] - time[0];
    if let Some(k) = time
        .windows(2)
        .position(|w| ((w[1] - w[0]) / period - 1.0).abs() > 0.01)
    {
        return Err(format!(
            "{file}:{}: column `time`: uneven sampling ({} s after {} s); resample to a fixed period",
            k + 3,
            time[k + 1] - time[k],
            period
        ));
    }
    Ok(Measured { time, columns })
}

/// One record handed to the workflow: how the bench was driven and what it recorded.
#[derive(Clone)]
pub struct Record {
    /// What the reports call it (the data file's stem).
    pub name: String,
    pub experiment: Experiment,
    pub measured: Measured,
}

/// The records of a command line: `--data` and `--experiment` paired in order, named by
/// the data file's stem; when two stems are equal (every `hbench hide` writes
/// `measured.csv`), by the folder holding the file, and by position when those are equal
/// too.
pub fn load_records(data: &[PathBuf], experiments: &[PathBuf]) -> Result<Vec<Record>, String> {
    if data.is_empty() || data.len() != experiments.len() {
        return Err(format!(
            "{} --data and {} --experiment: give one experiment file per data file, in the same order",
            data.len(),
            experiments.len()
        ));
    }
    let stem = |p: &Path| {
        p.file_stem()
            .map_or("record".into(), |s| s.to_string_lossy().into_owned())
    };
    let folder = |p: &Path| {
        p.canonicalize()
            .ok()
            .and_then(|c| {
                c.parent()?
                    .file_name()
                    .map(|f| f.to_string_lossy().into_owned())
            })
            .unwrap_or_else(|| stem(p))
    };
    let unique = |name: &dyn Fn(&Path) -> String| {
        let names: Vec<String> = data.iter().map(|d| name(d)).collect();
        let distinct: std::collections::BTreeSet<&String> = names.iter().collect();
        (distinct.len() == names.len()).then_some(names)
    };
    let names = unique(&stem)
        .or_else(|| unique(&folder))
        .unwrap_or_else(|| (1..=data.len()).map(|k| format!("record{k}")).collect());
    let mut records = Vec::with_capacity(data.len());
    for ((d, x), name) in data.iter().zip(experiments).zip(names) {
        let experiment = load_experiment(x)?;
        let measured = load_measured(d, &experiment)?;
        records.push(Record {
            name,
            experiment,
            measured,
        });
    }
    Ok(records)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn experiment() -> Experiment {
        Experiment {
            mode: 3,
            supply_pressure: 210e5,
            tank_pressure: 2e5,
            initial_position: 0.0,
            drive: Drive::Proportional {
                kp: 1169.0,
                reference: "y_ref".into(),
            },
        }
    }

    fn write(name: &str, text: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("hb-gap-data-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    fn csv(rows: &[&str]) -> String {
        let mut s = String::from("time,y_ref,y,P1\n");
        for k in 0..20 {
            let row = rows
                .iter()
                .find(|r| r.starts_with(&format!("{k}:")))
                .map(|r| r.split_once(':').unwrap().1.to_string())
                .unwrap_or_else(|| format!("{},0,0,1e7", k as f64 * 1e-3));
            s.push_str(&row);
            s.push('\n');
        }
        s
    }

    #[test]
    fn experiment_round_trips_and_errors_name_the_field() {
        let e = experiment();
        let p = write("ok.toml", &e.to_toml());
        assert_eq!(load_experiment(&p).unwrap(), e);
        let p = write("bad.toml", &e.to_toml().replace("mode = 3", "mode = 4"));
        let err = load_experiment(&p).unwrap_err();
        assert!(
            err.contains("bad.toml:1") && err.contains("`mode`"),
            "{err}"
        );
    }

    #[test]
    fn measured_errors_name_row_and_column() {
        let e = experiment();
        let ok = load_measured(&write("ok.csv", &csv(&[])), &e).unwrap();
        assert_eq!(ok.time.len(), 20);
        let cases = [
            (csv(&["5:0.005,0,NaN,1e7"]), ":7: column `y`"),
            (csv(&["5:0.004,0,0,1e7"]), ":7: column `time`"),
            (csv(&["3:0.003,0,0,-5"]), ":5: column `P1`"),
            (
                csv(&[]).replace("y_ref,", "").replace("0,0,1e7", "0,1e7"),
                "missing column `y_ref`",
            ),
            (
                csv(&[]).replace("P1", "Pfoo"),
                "`Pfoo` is not a bench.fmu variable",
            ),
        ];
        for (text, expected) in cases {
            let err = load_measured(&write("m.csv", &text), &e).unwrap_err();
            assert!(err.contains(expected), "{err}");
        }
    }
}
