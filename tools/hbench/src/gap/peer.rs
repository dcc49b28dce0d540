//! The independent Python/scipy bench simulator (`tools/peer/bench_peer.py`, written from
//! the thesis, not from `model/`) as another bench for `hbench hide`: the experiment's
//! reference or commands go to it as a drive CSV and the truth's parameters as a variant
//! JSON; it returns what its sensors read and the commands it applied, sample by sample,
//! which `hide` then records through the same noise and quantisation as the Rust bench.

use std::path::PathBuf;
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};

use serde_json::{Map, Value};

use super::data::{Drive, Experiment};

/// Relative tolerance of the peer's integrator: its positions then lie within 1e-3 of
/// an rtol 1e-9 run on the thesis moves (tools/peer/README.md), far below the LVDT noise.
const PEER_RTOL: &str = "1e-6";

/// The peer's script: $HB_PEER, else tools/peer/bench_peer.py in this source tree.
pub fn script() -> PathBuf {
    std::env::var_os("HB_PEER").map_or_else(
        || {
            PathBuf::from(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../peer/bench_peer.py"
            ))
        },
        PathBuf::from,
    )
}

/// The interpreter: $HB_PYTHON, else the tree's .venv (tools/setup.sh installs scipy
/// there), else python3 on the PATH.
pub fn python() -> PathBuf {
    if let Some(p) = std::env::var_os("HB_PYTHON") {
        return PathBuf::from(p);
    }
    let venv = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../.venv/bin/python"
    ));
    if venv.is_file() {
        venv
    } else {
        PathBuf::from("python3")
    }
}

/// A scratch directory of its own per run (several cases may run at once).
fn scratch() -> Result<PathBuf, String> {
    static COUNT: AtomicUsize = AtomicUsize::new(0);
    let d = std::env::temp_dir().join(format!(
        "hbench-peer-{}-{}",
        std::process::id(),
        COUNT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&d).map_err(|e| format!("cannot create {}: {e}", d.display()))?;
    Ok(d)
}

/// Run the peer on `signal` (the reference in closed loop, u1 = -u2 in open loop), one
/// value per sample of `period`, with the truth's `variant` parameters. Returns per
/// sample [signal, y, P1, P2, u1] as the peer's sensors read them and its loop applied.
/// A run that fails keeps its scratch directory (drive, variant) and names it.
pub fn run(
    variant: &Map<String, Value>,
    experiment: &Experiment,
    signal: &[f64],
    period: f64,
) -> Result<Vec<[f64; 5]>, String> {
    let dir = scratch()?;
    match run_in(&dir, variant, experiment, signal, period) {
        Ok(rows) => {
            let _ = std::fs::remove_dir_all(&dir);
            Ok(rows)
        }
        // the inputs kept, to run the peer again by hand on what failed
        Err(e) => Err(format!("{e} (its inputs are kept in {})", dir.display())),
    }
}

fn run_in(
    dir: &std::path::Path,
    variant: &Map<String, Value>,
    e: &Experiment,
    signal: &[f64],
    period: f64,
) -> Result<Vec<[f64; 5]>, String> {
    let closed = matches!(e.drive, Drive::Proportional { .. });
    let mut drive = String::from(if closed {
        "time,y_ref\n"
    } else {
        "time,u1,u2\n"
    });
    for (k, s) in signal.iter().enumerate() {
        let t = k as f64 * period;
        if closed {
            drive.push_str(&format!("{t:.9},{s:e}\n"));
        } else {
            drive.push_str(&format!("{t:.9},{s:e},{:e}\n", -s));
        }
    }
    let mut v = variant.clone();
    v.insert("supply_pressure".into(), e.supply_pressure.into());
    v.insert("tank_pressure".into(), e.tank_pressure.into());
    let write = |name: &str, text: &str| {
        std::fs::write(dir.join(name), text).map_err(|err| format!("cannot write {name}: {err}"))
    };
    write("drive.csv", &drive)?;
    write("variant.json", &Value::Object(v).to_string())?;
    let kp = match e.drive {
        Drive::Proportional { kp, .. } => kp,
        Drive::OpenLoop => 0.0,
    };
    let out = dir.join("out.csv");
    let (py, script) = (python(), script());
    let status = Command::new(&py)
        .arg(&script)
        .args([
            "--drive",
            "drive.csv",
            "--variant",
            "variant.json",
            "--csv",
            "out.csv",
        ])
        .args(["--mode", &e.mode.to_string(), "--kp", &kp.to_string()])
        .args(["--y0", &e.initial_position.to_string(), "--rtol", PEER_RTOL])
        .current_dir(dir)
        .output()
        .map_err(|err| format!("cannot run {} {}: {err}", py.display(), script.display()))?;
    if !status.status.success() {
        return Err(format!(
            "the peer simulator failed: {}",
            String::from_utf8_lossy(&status.stderr).trim()
        ));
    }
    let text = std::fs::read_to_string(&out).map_err(|err| format!("peer output: {err}"))?;
    parse(&text, signal, closed)
}

/// The peer's CSV `time,y_ref,y,v,P1,P2,u1,u2` as [signal, y, P1, P2, u1] rows.
fn parse(text: &str, signal: &[f64], closed: bool) -> Result<Vec<[f64; 5]>, String> {
    let mut lines = text.lines();
    let header = lines.next().unwrap_or_default();
    if header != "time,y_ref,y,v,P1,P2,u1,u2" {
        return Err(format!("peer output: unexpected header '{header}'"));
    }
    let mut rows = Vec::with_capacity(signal.len());
    for (k, line) in lines.enumerate() {
        let f: Vec<f64> = line
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|err| format!("peer output row {}: {err}", k + 2))?;
        if f.len() != 8 || f.iter().any(|x| !x.is_finite()) {
            return Err(format!(
                "peer output row {}: expected 8 finite numbers",
                k + 2
            ));
        }
        let s = if closed { f[1] } else { signal[k] };
        rows.push([s, f[2], f[4], f[5], f[6]]);
    }
    if rows.len() != signal.len() {
        return Err(format!(
            "peer output: {} samples for a drive of {}",
            rows.len(),
            signal.len()
        ));
    }
    Ok(rows)
}
