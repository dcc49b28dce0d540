//! `hbench sweep`: parameter studies and robustness sweeps. The work is done by the
//! project's Python runner (`tools/sweep`, over fmpy and Dask) in the project's venv;
//! this command finds both and hands over its arguments unchanged.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The workspace holding `tools/sweep`: the one hbench was built from, else the one
/// around the running program (target/release/hbench).
fn workspace() -> Result<PathBuf, String> {
    let built = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let running = std::env::current_exe()
        .ok()
        .and_then(|exe| exe.parent()?.parent()?.parent().map(Path::to_path_buf));
    [Some(built), running]
        .into_iter()
        .flatten()
        .find(|w| w.join("tools/sweep/__main__.py").is_file())
        .ok_or_else(|| "cannot find tools/sweep (the sweep runner) beside this hbench".into())
}

pub fn main(args: &[String]) -> Result<(), String> {
    let workspace = workspace()?;
    let python = workspace.join(".venv/bin/python");
    if !python.is_file() {
        return Err(format!(
            "the project's Python venv is missing ({}): run `bash tools/setup.sh`, which \
             creates it with fmpy, dask[distributed] and matplotlib",
            python.display()
        ));
    }
    let tools = workspace.join("tools");
    let pythonpath = match std::env::var_os("PYTHONPATH") {
        Some(old) if !old.is_empty() => {
            let mut p = tools.into_os_string();
            p.push(":");
            p.push(old);
            p
        }
        _ => tools.into_os_string(),
    };
    let mut cmd = Command::new(&python);
    cmd.args(["-m", "sweep"])
        .args(args)
        .env("PYTHONPATH", pythonpath);
    if let Ok(exe) = std::env::current_exe() {
        // the runner asks this hbench for the scenarios (`hbench simulate --inputs-only`)
        cmd.env("HBENCH", exe);
    }
    run(cmd, &python)
}

#[cfg(unix)]
fn run(mut cmd: Command, python: &Path) -> Result<(), String> {
    use std::os::unix::process::CommandExt;
    // exec only returns on failure; on success the runner's exit code is hbench's
    let e = cmd.exec();
    Err(format!("cannot run {}: {e}", python.display()))
}

#[cfg(not(unix))]
fn run(mut cmd: Command, python: &Path) -> Result<(), String> {
    let status = cmd
        .status()
        .map_err(|e| format!("cannot run {}: {e}", python.display()))?;
    std::process::exit(status.code().unwrap_or(1))
}
