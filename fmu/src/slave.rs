//! What a model offers the FMI shim: its variables, declared once, and its behaviour.
//!
//! A variable's declaration carries both what `modelDescription.xml` says of it and how
//! the C ABI reads and writes it, so the two cannot drift apart. Value references are
//! the variables' positions in the list.

use std::path::Path;

use modeldesc::{DefaultExperiment, Initial, ScalarVariable, VarKind};

/// A value crossing the ABI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    Real(f64),
    Integer(i32),
    Boolean(bool),
}

type Get<M> = Box<dyn Fn(&M) -> Value + Send + Sync>;
type Set<M> = Box<dyn Fn(&mut M, Value) -> Result<(), String> + Send + Sync>;

/// One variable: its declaration and its accessors.
pub struct VarDef<M> {
    pub decl: ScalarVariable,
    pub get: Get<M>,
    pub set: Option<Set<M>>,
    /// For an output: the inputs it depends on at the same instant (direct
    /// feedthrough); None means all, as far as the model description says.
    pub depends_on: Option<&'static [&'static str]>,
}

impl<M> VarDef<M> {
    /// Declare an output's direct feedthrough (an empty list: none).
    pub fn depends_on(mut self, inputs: &'static [&'static str]) -> Self {
        self.depends_on = Some(inputs);
        self
    }
}

impl<M> VarDef<M> {
    /// A declaration (value reference assigned later, by position) with its accessors.
    fn new(decl: ScalarVariable, get: Get<M>, set: Option<Set<M>>) -> Self {
        VarDef {
            decl,
            get,
            set,
            depends_on: None,
        }
    }
}

/// The registry writes dimensionless units as "1"; model descriptions leave them out.
fn si_unit(unit: &str) -> &str {
    if unit == "1" {
        ""
    } else {
        unit
    }
}

/// Add the project's display unit for an SI unit, if it has one.
fn displayed(decl: ScalarVariable, unit: &str) -> ScalarVariable {
    match display_unit(unit) {
        Some(d) => decl.with_display_unit(d),
        None => decl,
    }
}

/// The display unit the project shows for an SI unit.
pub fn display_unit(unit: &str) -> Option<&'static str> {
    match unit {
        "Pa" => Some("bar"),
        "m3/s" => Some("L/min"),
        "m" => Some("mm"),
        _ => None,
    }
}

/// Relative distance past a declared input bound that is clamped to the bound rather than
/// refused: 1e-6 takes the 1.5e-8 overshoot measured from OMSimulator's KINSOL (10 uV on
/// a 10 V command) with margin, and is far below any physically meaningful excess.
const INPUT_BOUND_SLACK: f64 = 1e-6;

/// A continuous real input with a start value and optional bounds.
/// Reads a real variable out of a model.
pub type RealGetter<M> = fn(&M) -> f64;
/// Writes a real variable into a model.
pub type RealSetter<M> = fn(&mut M, f64);

pub fn real_input<M: 'static>(
    name: &str,
    description: &str,
    unit: &str,
    start: f64,
    bounds: (Option<f64>, Option<f64>),
    get: impl Fn(&M) -> f64 + Send + Sync + 'static,
    set: impl Fn(&mut M, f64) + Send + Sync + 'static,
) -> VarDef<M> {
    let (min, max) = bounds;
    let mut decl = displayed(
        ScalarVariable::real_input(name, 0, description, si_unit(unit), start),
        unit,
    );
    if let VarKind::Real {
        min: lo, max: hi, ..
    } = &mut decl.kind
    {
        (*lo, *hi) = (min, max);
    }
    VarDef::new(
        decl,
        Box::new(move |m| Value::Real(get(m))),
        Some(Box::new(move |m, v| match v {
            Value::Real(x) => {
                if !x.is_finite() {
                    return Err(format!("input {x} is not a finite number"));
                }
                // masters land a little past a bound: interpolation rounds (10 V becomes
                // 10.000000000000002) and OMSimulator's KINSOL loop solver overshoots a
                // saturated command to 10.00000015 V; clamp within INPUT_BOUND_SLACK,
                // refuse the rest
                let slack = |b: f64| INPUT_BOUND_SLACK * b.abs().max(1.0);
                if min.is_some_and(|lo| x < lo - slack(lo))
                    || max.is_some_and(|hi| x > hi + slack(hi))
                {
                    return Err(format!("input {x} lies outside [{min:?}, {max:?}]"));
                }
                let x = x.clamp(
                    min.unwrap_or(f64::NEG_INFINITY),
                    max.unwrap_or(f64::INFINITY),
                );
                set(m, x);
                Ok(())
            }
            _ => Err("not a Real variable".into()),
        })),
    )
}

/// A continuous real output, calculated by the model.
pub fn real_output<M: 'static>(
    name: &str,
    description: &str,
    unit: &str,
    get: impl Fn(&M) -> f64 + Send + Sync + 'static,
) -> VarDef<M> {
    let decl = ScalarVariable::real_output(name, 0, description, si_unit(unit));
    VarDef::new(
        displayed(decl, unit).with_initial(Initial::Calculated),
        Box::new(move |m| Value::Real(get(m))),
        None,
    )
}

/// A fixed real parameter with physical bounds; setting it out of bounds is refused.
#[allow(clippy::too_many_arguments)]
pub fn real_parameter<M: 'static>(
    name: &str,
    description: &str,
    unit: &str,
    start: f64,
    min: f64,
    max: f64,
    get: impl Fn(&M) -> f64 + Send + Sync + 'static,
    set: impl Fn(&mut M, f64) + Send + Sync + 'static,
) -> VarDef<M> {
    let decl = ScalarVariable::real_parameter(name, 0, description, si_unit(unit), start);
    VarDef::new(
        displayed(decl, unit)
            .with_real_range(min, max)
            .with_initial(Initial::Exact),
        Box::new(move |m| Value::Real(get(m))),
        Some(Box::new(move |m, v| match v {
            Value::Real(x) if x.is_finite() && x >= min && x <= max => {
                set(m, x);
                Ok(())
            }
            Value::Real(x) => Err(format!(
                "{x} lies outside the physical bounds [{min}, {max}]"
            )),
            _ => Err("not a Real variable".into()),
        })),
    )
}

/// A fixed integer parameter within bounds.
pub fn integer_parameter<M: 'static>(
    name: &str,
    description: &str,
    start: i32,
    min: i32,
    max: i32,
    get: fn(&M) -> i32,
    set: fn(&mut M, i32),
) -> VarDef<M> {
    VarDef::new(
        ScalarVariable::integer_parameter(name, 0, description, start)
            .with_integer_range(min, max)
            .with_initial(Initial::Exact),
        Box::new(move |m| Value::Integer(get(m))),
        Some(Box::new(move |m, v| match v {
            Value::Integer(x) if (min..=max).contains(&x) => {
                set(m, x);
                Ok(())
            }
            Value::Integer(x) => Err(format!("{x} lies outside [{min}, {max}]")),
            _ => Err("not an Integer variable".into()),
        })),
    )
}

/// A selectable option: an Integer parameter whose values 1..=n stand for `options`
/// (name, meaning), listed in its description as "k = name (meaning)". Not an FMI
/// Enumeration: DNV's libcosim ignores Enumeration variables, while fmpy, OMSimulator and
/// libcosim all set an Integer (docs/engines.md). The names stay machine-readable in the
/// description for tools that take them (tools/sweep).
pub fn enum_parameter<M: 'static>(
    name: &str,
    description: &str,
    options: &[(&str, &str)],
    start: i32,
    get: fn(&M) -> i32,
    set: fn(&mut M, i32),
) -> VarDef<M> {
    let listing: Vec<String> = options
        .iter()
        .enumerate()
        .map(|(i, (n, meaning))| format!("{} = {n} ({meaning})", i + 1))
        .collect();
    integer_parameter(
        name,
        &format!("{description}: {}", listing.join("; ")),
        start,
        1,
        options.len() as i32,
        get,
        set,
    )
}

/// A fixed Boolean parameter.
pub fn boolean_parameter<M: 'static>(
    name: &str,
    description: &str,
    start: bool,
    get: impl Fn(&M) -> bool + Send + Sync + 'static,
    set: impl Fn(&mut M, bool) + Send + Sync + 'static,
) -> VarDef<M> {
    VarDef::new(
        ScalarVariable::boolean_parameter(name, 0, description, start).with_initial(Initial::Exact),
        Box::new(move |m| Value::Boolean(get(m))),
        Some(Box::new(move |m, v| match v {
            Value::Boolean(b) => {
                set(m, b);
                Ok(())
            }
            _ => Err("not a Boolean variable".into()),
        })),
    )
}

/// The same variable seen through a containing model `B` that holds an `A`.
pub fn project<A: 'static, B: 'static>(
    v: VarDef<A>,
    inner: fn(&B) -> &A,
    inner_mut: fn(&mut B) -> &mut A,
) -> VarDef<B> {
    let get = v.get;
    let set = v.set;
    VarDef {
        decl: v.decl,
        get: Box::new(move |b: &B| get(inner(b))),
        set: set.map(|s| -> Set<B> { Box::new(move |b: &mut B, x| s(inner_mut(b), x)) }),
        depends_on: v.depends_on,
    }
}

/// Static facts about a model.
pub struct ModelInfo {
    pub model_name: &'static str,
    pub model_identifier: &'static str,
    pub description: &'static str,
    pub default_experiment: DefaultExperiment,
    /// The thesis equations the model implements, one line each, for the documentation.
    pub equations: &'static [&'static str],
    /// The built-in parameter tree, shipped as resources/parameters.toml.
    pub parameters: Option<hbmodel::Params>,
}

/// A model behind the FMI shim. `Snapshot` is the complete state for get/set/serialize.
pub trait Model: Sized + Send + 'static {
    type Snapshot: Clone + Send + serde::Serialize + serde::de::DeserializeOwned;

    fn info() -> ModelInfo;
    fn variables() -> Vec<VarDef<Self>>;
    /// A new instance with defaults, overridden by `resources/parameters.toml` if present.
    fn instantiate(resources: Option<&Path>) -> Result<Self, String>;
    /// Parameters are final: check them and build the simulation.
    fn initialize(&mut self, start_time: f64) -> Result<(), String>;
    /// Make outputs consistent with the current state and inputs.
    fn refresh(&mut self) -> Result<(), String>;
    /// Advance from the current time by h with the current inputs.
    fn do_step(&mut self, h: f64) -> Result<(), String>;
    fn time(&self) -> f64;
    fn snapshot(&self) -> Self::Snapshot;
    fn restore(&mut self, s: Self::Snapshot) -> Result<(), String>;
    /// The integrator's relative tolerance, which fmi2SetupExperiment's tolerance sets;
    /// None for a model without an integrator.
    fn relative_tolerance(&mut self) -> Option<&mut f64> {
        None
    }
}

/// The model description of a model, value references assigned by position.
pub fn description<M: Model>() -> modeldesc::ModelDescription {
    let info = M::info();
    let defs = M::variables();
    let output_dependencies = defs
        .iter()
        .filter_map(|v| {
            v.depends_on.map(|d| {
                (
                    v.decl.name.clone(),
                    d.iter().map(|s| s.to_string()).collect(),
                )
            })
        })
        .collect();
    let variables = defs
        .into_iter()
        .enumerate()
        .map(|(i, v)| ScalarVariable {
            value_reference: i as u32,
            ..v.decl
        })
        .collect();
    modeldesc::ModelDescription {
        model_name: info.model_name.to_string(),
        model_identifier: info.model_identifier.to_string(),
        description: info.description.to_string(),
        generation_tool: format!("HydroBench {}", env!("CARGO_PKG_VERSION")),
        log_categories: crate::ffi::LOG_CATEGORIES
            .iter()
            .map(|(n, d)| (n.to_string(), d.to_string()))
            .collect(),
        default_experiment: Some(info.default_experiment),
        enumerations: vec![],
        variables,
        output_dependencies,
    }
}
