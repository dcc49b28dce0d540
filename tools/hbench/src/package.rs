//! `hbench fmu`: zip each model description with the shared library into an FMU.

use std::io::Write;
use std::path::{Path, PathBuf};

use zip::write::SimpleFileOptions;

/// FMI 2.0 platform folder of this build.
fn platform() -> &'static str {
    match (std::env::consts::OS, std::env::consts::ARCH) {
        ("linux", "x86_64") => "linux64",
        ("linux", "x86") => "linux32",
        ("macos", _) => "darwin64",
        ("windows", "x86_64") => "win64",
        _ => "linux64",
    }
}

fn library_name() -> &'static str {
    match std::env::consts::OS {
        "macos" => "libhbfmu.dylib",
        "windows" => "hbfmu.dll",
        _ => "libhbfmu.so",
    }
}

fn default_library() -> Result<PathBuf, String> {
    let exe = std::env::current_exe().map_err(|e| format!("cannot locate this program: {e}"))?;
    let dir = exe.parent().ok_or("this program has no directory")?;
    Ok(dir.join(library_name()))
}

/// Build the FMI library in release mode from the workspace this program was built in,
/// and return where cargo put it.
fn build_library() -> Result<PathBuf, String> {
    let workspace = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let manifest = workspace.join("Cargo.toml");
    if !manifest.is_file() {
        // an installed hbench without its sources: use the library shipped beside it
        return default_library();
    }
    eprintln!("hbench: building the FMI library (cargo build --release -p hydrobench-fmu)");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = std::process::Command::new(cargo)
        .args([
            "build",
            "--release",
            "-q",
            "-p",
            "hydrobench-fmu",
            "--manifest-path",
        ])
        .arg(&manifest)
        .status()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    if !status.success() {
        return Err("building the FMI library failed".into());
    }
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace.join("target"));
    Ok(target.join("release").join(library_name()))
}

pub fn run(
    out: &Path,
    lib: Option<PathBuf>,
    parameters: Option<PathBuf>,
    force: bool,
    xml: bool,
) -> Result<(), String> {
    let lib = match lib {
        Some(l) => l,
        None => build_library()?,
    };
    let binary = std::fs::read(&lib)
        .map_err(|e| format!("cannot read the FMI library {}: {e}", lib.display()))?;
    let user_params = match &parameters {
        Some(p) => {
            // refuse a bad file here rather than inside a host
            hbmodel::Params::load(p).map_err(|e| e.to_string())?;
            Some(
                std::fs::read_to_string(p)
                    .map_err(|e| format!("cannot read {}: {e}", p.display()))?,
            )
        }
        None => None,
    };
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let ext = Path::new(library_name())
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("so");
    for spec in hbfmu::models::specs() {
        let (id, description) = (spec.id, &spec.description);
        description
            .check()
            .map_err(|p| format!("{id}: invalid model description: {}", p.join("; ")))?;
        let path = out.join(format!("{id}.fmu"));
        if path.exists() && !force {
            return Err(format!(
                "{} exists; pass --force to replace it",
                path.display()
            ));
        }
        let text = description.to_xml();
        let file = std::fs::File::create(&path)
            .map_err(|e| format!("cannot create {}: {e}", path.display()))?;
        let mut zip = zip::ZipWriter::new(file);
        let opts =
            SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
        let mut add = |name: &str, bytes: &[u8]| -> Result<(), String> {
            zip.start_file(name, opts).map_err(|e| e.to_string())?;
            zip.write_all(bytes).map_err(|e| e.to_string())
        };
        add("modelDescription.xml", text.as_bytes())?;
        add(&format!("binaries/{}/{id}.{ext}", platform()), &binary)?;
        add("documentation/index.html", spec.documentation.as_bytes())?;
        // the user's parameter file replaces the built-in one
        if let Some(p) = user_params.as_ref().or(spec.parameters.as_ref()) {
            let name = format!("resources/{}", hbfmu::models::PARAMETER_FILE);
            add(&name, p.as_bytes())?;
        }
        zip.finish().map_err(|e| e.to_string())?;
        if xml {
            std::fs::write(out.join(format!("{id}.xml")), &text).map_err(|e| e.to_string())?;
        }
        println!("{}", path.display());
    }
    // the same FMUs wired into the bench as an SSP 1.0 system (hbench cosim, OMSimulator)
    println!("{}", crate::cosim::ssp::write_package(out)?.display());
    Ok(())
}
