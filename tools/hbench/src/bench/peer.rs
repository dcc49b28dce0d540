//! The Python/scipy peer simulator (tools/peer/bench_peer.py, written from the thesis
//! independently of model/) run on the same scenario, for the speed ratio.
//!
//! Contract (docs in the peer): `--scenario moves --duration S --mode 3 --rtol R --kp K
//! --json --csv OUT` prints one JSON object with `cpu_seconds` (process time around its
//! integration loop) and writes the 1 kHz trace with a `y` column.

use std::path::{Path, PathBuf};
use std::process::Command;

/// One peer run.
pub struct PeerRun {
    pub cpu: f64,
    pub steps: u64,
    pub rhs: u64,
    pub jacobians: u64,
    pub positions: Vec<f64>,
}

/// Where the peer and the Python that runs it are, or why they are not usable.
pub struct Peer {
    python: PathBuf,
    script: PathBuf,
}

impl Peer {
    /// Finds `tools/peer/bench_peer.py` under the current directory or the source tree,
    /// and the project venv's Python (`HBENCH_PEER_PYTHON` overrides it).
    pub fn locate() -> Result<Peer, String> {
        let roots = [
            PathBuf::from("."),
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../.."),
        ];
        let root = roots
            .iter()
            .find(|r| r.join("tools/peer/bench_peer.py").is_file())
            .ok_or("tools/peer/bench_peer.py is absent (the peer simulator of issue 14)")?;
        let python = match std::env::var_os("HBENCH_PEER_PYTHON") {
            Some(p) => PathBuf::from(p),
            None => root.join(".venv/bin/python"),
        };
        if !python.is_file() {
            return Err(format!(
                "no Python at {} (run tools/setup.sh or set HBENCH_PEER_PYTHON)",
                python.display()
            ));
        }
        Ok(Peer {
            python,
            script: root.join("tools/peer/bench_peer.py"),
        })
    }

    /// The moves in mode 3 under P control `kp` for `seconds` at `rtol`.
    pub fn run(&self, seconds: f64, rtol: f64, kp: f64) -> Result<PeerRun, String> {
        let csv =
            std::env::temp_dir().join(format!("hbench_peer_{}_{rtol:e}.csv", std::process::id()));
        let out = Command::new(&self.python)
            .arg(&self.script)
            .args(["--scenario", "moves", "--mode", "3", "--json"])
            .args(["--duration", &seconds.to_string()])
            .args(["--rtol", &rtol.to_string()])
            .args(["--kp", &kp.to_string()])
            .arg("--csv")
            .arg(&csv)
            .output()
            .map_err(|e| format!("cannot start the peer: {e}"))?;
        if !out.status.success() {
            return Err(format!(
                "the peer failed ({}): {}",
                out.status,
                String::from_utf8_lossy(&out.stderr).trim()
            ));
        }
        let v: serde_json::Value = serde_json::from_slice(&out.stdout)
            .map_err(|e| format!("the peer's JSON is unreadable: {e}"))?;
        let text = std::fs::read_to_string(&csv)
            .map_err(|e| format!("the peer wrote no trace {}: {e}", csv.display()));
        let _ = std::fs::remove_file(&csv);
        let positions = column(&text?, "y")?;
        let count = |k: &str| v[k].as_u64().unwrap_or(0);
        Ok(PeerRun {
            cpu: v["cpu_seconds"]
                .as_f64()
                .ok_or("the peer's JSON has no cpu_seconds")?,
            steps: count("steps"),
            rhs: count("rhs_evaluations"),
            jacobians: count("jacobian_evaluations"),
            positions,
        })
    }
}

/// The named column of a CSV with a header line.
fn column(text: &str, name: &str) -> Result<Vec<f64>, String> {
    let mut lines = text.lines();
    let header = lines.next().ok_or("the peer's trace is empty")?;
    let i = header
        .split(',')
        .position(|h| h.trim() == name)
        .ok_or_else(|| format!("the peer's trace has no '{name}' column"))?;
    lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            l.split(',')
                .nth(i)
                .and_then(|s| s.trim().parse::<f64>().ok())
                .ok_or_else(|| format!("bad line in the peer's trace: {l}"))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_csv_column_is_read_by_its_header_name() {
        let t = "time,y_ref,y\n0,1,2.5\n0.001,1,-3e-3\n";
        assert_eq!(column(t, "y").unwrap(), vec![2.5, -3e-3]);
        assert!(column(t, "P1").is_err());
        assert!(column("time,y\n0,x\n", "y").is_err());
    }
}
