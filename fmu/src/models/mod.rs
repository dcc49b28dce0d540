//! The HydroBench FMUs and how an instantiation finds its model.

pub mod actuator;
pub mod bench;
pub mod closed_loop;
pub mod component;
pub mod controller;
pub mod manifold;
pub mod reference;
pub mod servovalve;

use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

use hbmodel::effects::Effect;
use hbmodel::params::ValveModel;
use hbmodel::params::{ParamSpec, PARAMS};
use hbmodel::Params;

use crate::instance::{Component, Instance, Logger};
use crate::slave::{boolean_parameter, description, real_parameter, Model, VarDef};

/// What packaging and instantiation need of one FMU.
pub struct FmuSpec {
    pub id: &'static str,
    pub description: modeldesc::ModelDescription,
    /// Derived from the description's content.
    pub guid: String,
    /// `resources/parameters.toml`: the built-in parameter tree, if the model has one.
    pub parameters: Option<String>,
    /// `documentation/index.html`.
    pub documentation: String,
}

/// Every FMU of the library, built once (packaging and tests).
pub fn specs() -> &'static [FmuSpec] {
    static ALL: OnceLock<Vec<FmuSpec>> = OnceLock::new();
    ALL.get_or_init(build_specs)
}

/// Every FMU of the library, freshly built.
fn build_specs() -> Vec<FmuSpec> {
    fn one<M: Model>() -> FmuSpec {
        let d = description::<M>();
        let info = M::info();
        FmuSpec {
            id: info.model_identifier,
            guid: d.guid(),
            parameters: info.parameters.map(|p| p.to_toml()),
            documentation: crate::docs::index_html(&d, info.equations),
            description: d,
        }
    }
    vec![
        one::<servovalve::ServovalveFmu>(),
        one::<manifold::ManifoldFmu>(),
        one::<actuator::ActuatorFmu>(),
        one::<bench::BenchFmu>(),
        one::<controller::ControllerFmu>(),
        one::<closed_loop::ClosedLoopFmu>(),
        one::<reference::ReferenceFmu>(),
    ]
}

/// Create the instance of the model whose description has this GUID.
pub fn instantiate(
    guid: &str,
    log: Logger,
    resources: Option<PathBuf>,
) -> Result<Box<dyn Component>, (Logger, String)> {
    let Some(id) = model_of_guid(guid) else {
        return Err((log, format!("no HydroBench model has GUID {guid}: the FMU's modelDescription.xml and binary differ in version")));
    };
    fn make<M: Model>(
        log: Logger,
        resources: Option<PathBuf>,
    ) -> Result<Box<dyn Component>, (Logger, String)> {
        Instance::<M>::new(log, resources).map(|i| Box::new(i) as Box<dyn Component>)
    }
    match id {
        "servovalve" => make::<servovalve::ServovalveFmu>(log, resources),
        "manifold" => make::<manifold::ManifoldFmu>(log, resources),
        "actuator" => make::<actuator::ActuatorFmu>(log, resources),
        "bench" => make::<bench::BenchFmu>(log, resources),
        "bench_closed_loop" => make::<closed_loop::ClosedLoopFmu>(log, resources),
        "reference" => make::<reference::ReferenceFmu>(log, resources),
        _ => make::<controller::ControllerFmu>(log, resources),
    }
}

/// GUID to model identifier of every model, built on the first instantiation. Not
/// [`specs`]: instantiation needs only the GUIDs, and this cache is one the library can
/// free when it is unloaded (`forget_guids`), so reloading it leaks nothing.
static GUIDS: Mutex<Vec<(String, &'static str)>> = Mutex::new(Vec::new());

fn model_of_guid(guid: &str) -> Option<&'static str> {
    let mut guids = GUIDS.lock().ok()?;
    if guids.is_empty() {
        *guids = build_specs().into_iter().map(|s| (s.guid, s.id)).collect();
    }
    guids.iter().find(|(g, _)| g == guid).map(|(_, id)| *id)
}

/// Free the GUID cache (the library is being unloaded).
pub fn forget_guids() {
    if let Ok(mut g) = GUIDS.lock() {
        std::mem::take(&mut *g);
    }
}

/// The resources directory an instance reads, from the host's `fmuResourceLocation`; when
/// it cannot be used, the built-in thesis parameters apply and the host is warned, naming
/// what was expected, since a parameter file the user shipped would otherwise be ignored
/// without a word (issue 16, item 3).
pub fn resources_or_warn(uri: Option<&str>, is_null: bool, log: &Logger) -> Option<PathBuf> {
    const EXPECTED: &str = "expected a file:// URI of the unpacked FMU's resources directory, e.g. file:///tmp/fmu/resources";
    const FALLBACK: &str =
        "resources/parameters.toml is not read, the built-in thesis parameters apply";
    let warn = |why: String| log.warn(&format!("fmi2Instantiate: {why}; {FALLBACK} ({EXPECTED})"));
    let Some(uri) = uri else {
        warn(if is_null {
            "fmuResourceLocation is NULL".into()
        } else {
            "fmuResourceLocation is not UTF-8".into()
        });
        return None;
    };
    let Some(dir) = resource_dir(uri) else {
        warn(format!(
            "fmuResourceLocation {uri:?} is not a local file URI with valid escapes"
        ));
        return None;
    };
    if !dir.is_dir() {
        // an FMU without resources (the controller's) leaves nothing to read: no warning
        return None;
    }
    let nested = dir.join("resources").join(PARAMETER_FILE);
    if !dir.join(PARAMETER_FILE).is_file() && nested.is_file() {
        warn(format!(
            "fmuResourceLocation {uri:?} names the FMU's root, not its resources directory, so {} is ignored",
            nested.display()
        ));
    }
    Some(dir)
}

/// The directory behind an `fmuResourceLocation` URI (file:///..., file:/...,
/// file://localhost/...); None for a remote host, a relative path or a bad escape.
pub fn resource_dir(uri: &str) -> Option<PathBuf> {
    let rest = uri
        .strip_prefix("file://")
        .or_else(|| uri.strip_prefix("file:"))?;
    // file:///path and file://localhost/path both name /path; file://host/path is remote
    let rest = rest.strip_prefix("localhost").unwrap_or(rest);
    if !rest.starts_with('/') {
        return None;
    }
    // percent-decoding: hosts escape spaces and non-ASCII characters
    let mut bytes = Vec::with_capacity(rest.len());
    let mut it = rest.bytes();
    while let Some(b) = it.next() {
        if b == b'%' {
            let hex = [it.next()?, it.next()?];
            bytes.push(u8::from_str_radix(std::str::from_utf8(&hex).ok()?, 16).ok()?);
        } else {
            bytes.push(b);
        }
    }
    Some(PathBuf::from(String::from_utf8(bytes).ok()?))
}

/// Name of the optional parameter file in an FMU's resources.
pub const PARAMETER_FILE: &str = "parameters.toml";

/// Parameters from `resources/parameters.toml` when the FMU ships one, else `default`.
pub fn load_params(resources: Option<&Path>, default: Params) -> Result<Params, String> {
    match resources.map(|r| r.join(PARAMETER_FILE)) {
        Some(file) if file.is_file() => Params::load(&file).map_err(|e| e.to_string()),
        _ => Ok(default),
    }
}

/// Bounds of absolute-pressure inputs (Pa): never negative; 1000 bar is five times the
/// bench's 210 bar supply, so a value above it is a unit or wiring error of the master.
pub const PRESSURE_INPUT: (Option<f64>, Option<f64>) = (Some(0.0), Some(1e8));

/// Bounds of external-force inputs (N): five times the 20 kN the actuator produces at
/// 210 bar (9.456 cm2), beyond which the input cannot be a load of this bench.
pub const FORCE_INPUT: (Option<f64>, Option<f64>) = (Some(-1e5), Some(1e5));

/// Bounds of servovalve commands (V): the D765's rated input.
pub const COMMAND_INPUT: (Option<f64>, Option<f64>) = (Some(-10.0), Some(10.0));

/// The servovalve models a valve parameter can select (name, meaning), values 1 and 2.
pub const VALVE_MODELS: [(&str, &str); 2] = [
    (
        "reduced",
        "static flow law (II.2), optional second-order spool",
    ),
    ("two_stage", "physical two-stage model of chapter 2"),
];

pub fn valve_model_code(m: ValveModel) -> i32 {
    match m {
        ValveModel::Reduced => 1,
        ValveModel::TwoStage => 2,
    }
}

pub fn valve_model_from(code: i32) -> ValveModel {
    if code == 2 {
        ValveModel::TwoStage
    } else {
        ValveModel::Reduced
    }
}

/// The default parameter tree with exactly these effects on.
pub fn params_with(effects: &[Effect]) -> Params {
    let mut p = Params::default();
    for e in effects {
        p.effects.set(*e, true);
    }
    p
}

/// Models that hold a bench parameter tree.
pub trait HasParams {
    fn params(&self) -> &Params;
    /// Mutable access; the model rebuilds its simulation before the next use.
    fn params_mut(&mut self) -> &mut Params;
}

/// FMU names of the registry paths the issue fixes; the rest keep their dotted path.
pub fn fmu_name(path: &str) -> &str {
    match path {
        "supply_pressure" => "P_supply",
        "tank_pressure" => "P_tank",
        "initial_position" => "y0",
        "actuator.payload_mass" => "payload_mass",
        other => other,
    }
}

/// Real parameters for the registry entries `keep` accepts, renamed by `rename`.
pub fn registry_parameters<M: HasParams + 'static>(
    keep: impl Fn(&str) -> bool,
    rename: impl Fn(&str) -> String,
) -> Vec<VarDef<M>> {
    PARAMS
        .iter()
        .filter(|spec| spec.path != FIXED_STEP && keep(spec.path))
        .map(|spec| registry_parameter(spec, &rename(fmu_name(spec.path))))
        .collect()
}

/// A registry parameter as a real FMU parameter named `name`, read and written in the
/// model's parameter tree.
fn registry_parameter<M: HasParams + 'static>(spec: &'static ParamSpec, name: &str) -> VarDef<M> {
    real_parameter(
        name,
        spec.description,
        spec.unit,
        spec.default_value(),
        spec.min,
        spec.max,
        move |m: &M| spec.get(m.params()),
        move |m: &mut M, v| spec.set(m.params_mut(), v),
    )
}

/// The real-time mode's step, which every FMU with an integrator declares last so that
/// the value references it had before the mode existed keep their numbers.
pub const FIXED_STEP: &str = "solver.fixed_step";

/// The `solver.fixed_step` parameter (see [`FIXED_STEP`]), as the registry declares it.
///
/// Found by filtering the registry rather than by a look-up that could fail, so no
/// panic path exists here; the registry always holds it (params::PARAMS), and
/// `tests/python/test_realtime.py` checks it is the last variable of every FMU with an
/// integrator.
pub fn fixed_step_parameter<M: HasParams + 'static>() -> impl Iterator<Item = VarDef<M>> {
    PARAMS
        .iter()
        .filter(|spec| spec.path == FIXED_STEP)
        .map(|spec| registry_parameter(spec, FIXED_STEP))
}

/// `effect.<name>` Boolean switches for the given effects.
pub fn effect_switches<M: HasParams + 'static>(
    effects: &[Effect],
    defaults: &Params,
) -> Vec<VarDef<M>> {
    effects
        .iter()
        .map(|&e| {
            boolean_parameter(
                &format!("effect.{}", e.name()),
                e.spec().description,
                defaults.has(e),
                move |m: &M| m.params().has(e),
                move |m: &mut M, on| m.params_mut().effects.set(e, on),
            )
        })
        .collect()
}
