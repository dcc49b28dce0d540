//! FMI 2.0 Co-Simulation model descriptions for the HydroBench FMUs.
//!
//! Each FMU declares its variables once, as a `Vec<ScalarVariable>`. The same declarations
//! give `modelDescription.xml` ([`ModelDescription::to_xml`]) and the value-reference
//! look-ups of the FMU's C ABI ([`ModelDescription::find`]), so the two cannot drift apart.
//! [`ModelDescription::check`] enforces the FMI 2.0 rules that the XML schema alone does not
//! (start values, causality/variability/initial combinations, units, ...), the ones
//! importers such as fmpy and OpenModelica reject FMUs for.
//!
//! ```
//! use modeldesc::*;
//!
//! let md = ModelDescription {
//!     model_name: "Orifice".into(),
//!     model_identifier: "orifice".into(),
//!     description: "Turbulent orifice".into(),
//!     generation_tool: "HydroBench 0.1.0".into(),
//!     log_categories: vec![("logAll".into(), "everything".into())],
//!     default_experiment: Some(DefaultExperiment {
//!         start_time: 0.0, stop_time: 1.0, tolerance: None, step_size: Some(1e-3),
//!     }),
//!     enumerations: vec![],
//!     variables: vec![
//!         ScalarVariable::real_parameter("Cd", 0, "discharge coefficient", "", 0.7),
//!         ScalarVariable::real_input("dp", 1, "pressure drop", "Pa", 1e5).with_display_unit("bar"),
//!         ScalarVariable::real_output("q", 2, "flow rate", "m3/s").with_display_unit("L/min"),
//!     ],
//!     output_dependencies: [("q".to_string(), vec!["dp".to_string()])].into(),
//! };
//! md.check().unwrap();
//! let xml = md.to_xml();
//! assert!(xml.contains(&md.guid()));
//! ```

mod check;
mod names;
mod units;
mod xml;

pub use units::{find_unit, unit_definitions, BaseUnit, DisplayUnit, Unit};

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

/// FMI 2.0 `causality` of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "camelCase"))]
pub enum Causality {
    Parameter,
    CalculatedParameter,
    Input,
    Output,
    Local,
    Independent,
}

impl Causality {
    /// The attribute value in modelDescription.xml.
    pub fn as_str(self) -> &'static str {
        match self {
            Causality::Parameter => "parameter",
            Causality::CalculatedParameter => "calculatedParameter",
            Causality::Input => "input",
            Causality::Output => "output",
            Causality::Local => "local",
            Causality::Independent => "independent",
        }
    }
}

/// FMI 2.0 `variability` of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "camelCase"))]
pub enum Variability {
    Constant,
    Fixed,
    Tunable,
    Discrete,
    Continuous,
}

impl Variability {
    /// The attribute value in modelDescription.xml.
    pub fn as_str(self) -> &'static str {
        match self {
            Variability::Constant => "constant",
            Variability::Fixed => "fixed",
            Variability::Tunable => "tunable",
            Variability::Discrete => "discrete",
            Variability::Continuous => "continuous",
        }
    }
}

/// FMI 2.0 `initial` of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "camelCase"))]
pub enum Initial {
    Exact,
    Approx,
    Calculated,
}

impl Initial {
    /// The attribute value in modelDescription.xml.
    pub fn as_str(self) -> &'static str {
        match self {
            Initial::Exact => "exact",
            Initial::Approx => "approx",
            Initial::Calculated => "calculated",
        }
    }
}

/// The FMI 2.0 C base type through which a variable is read and written
/// (`fmi2GetReal`, `fmi2GetInteger`, ...). Value references are unique per base type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BaseType {
    Real,
    /// Integer and Enumeration variables: both go through `fmi2Get/SetInteger`.
    Integer,
    Boolean,
    String,
}

/// Type and type-specific attributes of a variable (the child element of `ScalarVariable`).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub enum VarKind {
    Real {
        start: Option<f64>,
        min: Option<f64>,
        max: Option<f64>,
        /// Name of a unit of [`unit_definitions`]; `None` for a dimensionless value.
        unit: Option<String>,
        /// Name of one of the unit's display units.
        display_unit: Option<String>,
    },
    Integer {
        start: Option<i32>,
        min: Option<i32>,
        max: Option<i32>,
    },
    Boolean {
        start: Option<bool>,
    },
    Enumeration {
        /// Name of an [`EnumerationType`] of the same model description.
        declared_type: String,
        start: Option<i32>,
        min: Option<i32>,
        max: Option<i32>,
    },
    String {
        start: Option<String>,
    },
}

impl VarKind {
    /// The C base type the FMU's get/set functions use for this kind.
    pub fn base_type(&self) -> BaseType {
        match self {
            VarKind::Real { .. } => BaseType::Real,
            VarKind::Integer { .. } | VarKind::Enumeration { .. } => BaseType::Integer,
            VarKind::Boolean { .. } => BaseType::Boolean,
            VarKind::String { .. } => BaseType::String,
        }
    }

    /// The element name in modelDescription.xml.
    pub fn element_name(&self) -> &'static str {
        match self {
            VarKind::Real { .. } => "Real",
            VarKind::Integer { .. } => "Integer",
            VarKind::Boolean { .. } => "Boolean",
            VarKind::Enumeration { .. } => "Enumeration",
            VarKind::String { .. } => "String",
        }
    }

    /// Whether a start value is given.
    pub fn has_start(&self) -> bool {
        match self {
            VarKind::Real { start, .. } => start.is_some(),
            VarKind::Integer { start, .. } | VarKind::Enumeration { start, .. } => start.is_some(),
            VarKind::Boolean { start } => start.is_some(),
            VarKind::String { start } => start.is_some(),
        }
    }
}

/// One FMI 2.0 `ScalarVariable`.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct ScalarVariable {
    /// Name under the "structured" naming convention, e.g. `valve.u` or `'p A'`.
    pub name: String,
    pub value_reference: u32,
    pub description: String,
    pub causality: Causality,
    pub variability: Variability,
    /// `None` leaves the attribute out, so the standard's default for the
    /// causality/variability pair applies (see [`ScalarVariable::effective_initial`]).
    pub initial: Option<Initial>,
    pub kind: VarKind,
}

impl ScalarVariable {
    /// A variable with no `initial` attribute.
    pub fn new(
        name: impl Into<String>,
        value_reference: u32,
        description: impl Into<String>,
        causality: Causality,
        variability: Variability,
        kind: VarKind,
    ) -> Self {
        ScalarVariable {
            name: name.into(),
            value_reference,
            description: description.into(),
            causality,
            variability,
            initial: None,
            kind,
        }
    }

    /// Continuous Real input. `unit` "" means dimensionless.
    pub fn real_input(
        name: impl Into<String>,
        value_reference: u32,
        description: impl Into<String>,
        unit: &str,
        start: f64,
    ) -> Self {
        Self::new(
            name,
            value_reference,
            description,
            Causality::Input,
            Variability::Continuous,
            real_kind(Some(start), unit),
        )
    }

    /// Continuous Real output computed by the FMU (initial defaults to calculated, so no
    /// start value). `unit` "" means dimensionless.
    pub fn real_output(
        name: impl Into<String>,
        value_reference: u32,
        description: impl Into<String>,
        unit: &str,
    ) -> Self {
        Self::new(
            name,
            value_reference,
            description,
            Causality::Output,
            Variability::Continuous,
            real_kind(None, unit),
        )
    }

    /// Fixed Real parameter (set before initialisation only). `unit` "" means dimensionless.
    pub fn real_parameter(
        name: impl Into<String>,
        value_reference: u32,
        description: impl Into<String>,
        unit: &str,
        start: f64,
    ) -> Self {
        Self::new(
            name,
            value_reference,
            description,
            Causality::Parameter,
            Variability::Fixed,
            real_kind(Some(start), unit),
        )
    }

    /// Tunable Real parameter (may also change between communication points).
    pub fn real_tunable(
        name: impl Into<String>,
        value_reference: u32,
        description: impl Into<String>,
        unit: &str,
        start: f64,
    ) -> Self {
        Self::new(
            name,
            value_reference,
            description,
            Causality::Parameter,
            Variability::Tunable,
            real_kind(Some(start), unit),
        )
    }

    /// Fixed Boolean parameter, e.g. an effect switch.
    pub fn boolean_parameter(
        name: impl Into<String>,
        value_reference: u32,
        description: impl Into<String>,
        start: bool,
    ) -> Self {
        Self::new(
            name,
            value_reference,
            description,
            Causality::Parameter,
            Variability::Fixed,
            VarKind::Boolean { start: Some(start) },
        )
    }

    /// Fixed Integer parameter.
    pub fn integer_parameter(
        name: impl Into<String>,
        value_reference: u32,
        description: impl Into<String>,
        start: i32,
    ) -> Self {
        Self::new(
            name,
            value_reference,
            description,
            Causality::Parameter,
            Variability::Fixed,
            VarKind::Integer {
                start: Some(start),
                min: None,
                max: None,
            },
        )
    }

    /// Fixed Enumeration parameter of the named [`EnumerationType`].
    pub fn enumeration_parameter(
        name: impl Into<String>,
        value_reference: u32,
        description: impl Into<String>,
        declared_type: impl Into<String>,
        start: i32,
    ) -> Self {
        Self::new(
            name,
            value_reference,
            description,
            Causality::Parameter,
            Variability::Fixed,
            VarKind::Enumeration {
                declared_type: declared_type.into(),
                start: Some(start),
                min: None,
                max: None,
            },
        )
    }

    /// Sets `initial`.
    pub fn with_initial(mut self, initial: Initial) -> Self {
        self.initial = Some(initial);
        self
    }

    /// Sets the display unit of a Real variable (ignored for other kinds).
    pub fn with_display_unit(mut self, name: &str) -> Self {
        if let VarKind::Real { display_unit, .. } = &mut self.kind {
            *display_unit = Some(name.to_string());
        }
        self
    }

    /// Sets min and max of a Real variable (ignored for other kinds).
    pub fn with_real_range(mut self, lo: f64, hi: f64) -> Self {
        if let VarKind::Real { min, max, .. } = &mut self.kind {
            *min = Some(lo);
            *max = Some(hi);
        }
        self
    }

    /// Sets min and max of an Integer or Enumeration variable (ignored for other kinds).
    pub fn with_integer_range(mut self, lo: i32, hi: i32) -> Self {
        if let VarKind::Integer { min, max, .. } | VarKind::Enumeration { min, max, .. } =
            &mut self.kind
        {
            *min = Some(lo);
            *max = Some(hi);
        }
        self
    }

    /// The C base type of the variable's get/set functions.
    pub fn base_type(&self) -> BaseType {
        self.kind.base_type()
    }

    /// `initial` as the importer will read it: the explicit attribute, else the standard's
    /// default for the causality/variability pair. `None` where no `initial` applies
    /// (inputs, the independent variable, and illegal causality/variability pairs).
    pub fn effective_initial(&self) -> Option<Initial> {
        self.initial
            .or_else(|| check::initial_rule(self.causality, self.variability)?.default())
    }
}

fn real_kind(start: Option<f64>, unit: &str) -> VarKind {
    VarKind::Real {
        start,
        min: None,
        max: None,
        unit: (!unit.is_empty()).then(|| unit.to_string()),
        display_unit: None,
    }
}

/// A `TypeDefinitions/SimpleType` holding an `Enumeration`.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct EnumerationType {
    pub name: String,
    pub description: String,
    pub items: Vec<EnumItem>,
}

impl EnumerationType {
    /// The item with this value.
    pub fn item(&self, value: i32) -> Option<&EnumItem> {
        self.items.iter().find(|i| i.value == value)
    }
}

#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct EnumItem {
    pub name: String,
    pub value: i32,
    pub description: String,
}

#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct DefaultExperiment {
    pub start_time: f64,
    pub stop_time: f64,
    pub tolerance: Option<f64>,
    /// Preferred communication step size.
    pub step_size: Option<f64>,
}

/// Everything modelDescription.xml says about one Co-Simulation FMU.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct ModelDescription {
    pub model_name: String,
    /// Base name of the shared library (`binaries/<platform>/<modelIdentifier>.so`); must
    /// be a C identifier because importers also use it as a symbol prefix for static builds.
    pub model_identifier: String,
    pub description: String,
    /// E.g. "HydroBench 0.1.0".
    pub generation_tool: String,
    /// (name, description) of each log category.
    pub log_categories: Vec<(String, String)>,
    pub default_experiment: Option<DefaultExperiment>,
    pub enumerations: Vec<EnumerationType>,
    /// In ModelVariables order: index `i` here is ScalarVariable index `i + 1`.
    pub variables: Vec<ScalarVariable>,
    /// Direct feedthrough: output name -> the inputs it depends on at the same instant
    /// (an empty list: none). Outputs not listed depend on every known, so their
    /// `dependencies` attribute is omitted, as FMI 2.0 allows.
    pub output_dependencies: std::collections::BTreeMap<String, Vec<String>>,
}

impl ModelDescription {
    /// Checks the FMI 2.0 rules that importers enforce beyond the XML schema. Returns every
    /// problem found, one sentence each.
    pub fn check(&self) -> Result<(), Vec<String>> {
        let problems = check::problems(self);
        if problems.is_empty() {
            Ok(())
        } else {
            Err(problems)
        }
    }

    /// GUID derived from the content: the SHA-256 of the XML rendered with an empty guid,
    /// its first 128 bits formatted as `{xxxxxxxx-xxxx-xxxx-xxxx-xxxxxxxxxxxx}`.
    pub fn guid(&self) -> String {
        xml::guid_of(&xml::render(self, ""))
    }

    /// The complete modelDescription.xml (UTF-8, guid filled in).
    ///
    /// Renders whatever it is given; run [`ModelDescription::check`] first. Values that
    /// XML cannot carry are left out rather than written invalid: non-finite reals are
    /// omitted and characters XML 1.0 forbids are replaced with U+FFFD (check reports both).
    pub fn to_xml(&self) -> String {
        xml::render(self, &self.guid())
    }

    /// 1-based ScalarVariable indices of `ModelStructure/Outputs`: every output, in
    /// ModelVariables order.
    /// 1-based indices of the inputs an output depends on directly, if declared.
    pub fn dependency_indices(&self, output: &str) -> Option<Vec<usize>> {
        let names = self.output_dependencies.get(output)?;
        let mut idx: Vec<usize> = names
            .iter()
            .filter_map(|n| self.variables.iter().position(|v| &v.name == n))
            .map(|i| i + 1)
            .collect();
        idx.sort_unstable();
        Some(idx)
    }

    pub fn output_indices(&self) -> Vec<usize> {
        self.indices_where(|v| v.causality == Causality::Output)
    }

    /// 1-based ScalarVariable indices of `ModelStructure/InitialUnknowns`: outputs whose
    /// initial is approx or calculated, and all calculated parameters, in index order.
    /// (A Co-Simulation FMU exposes no derivatives, so no states enter this list.)
    pub fn initial_unknown_indices(&self) -> Vec<usize> {
        self.indices_where(|v| match v.causality {
            Causality::CalculatedParameter => true,
            Causality::Output => matches!(
                v.effective_initial(),
                Some(Initial::Approx | Initial::Calculated)
            ),
            _ => false,
        })
    }

    fn indices_where(&self, pred: impl Fn(&ScalarVariable) -> bool) -> Vec<usize> {
        self.variables
            .iter()
            .enumerate()
            .filter(|(_, v)| pred(v))
            .map(|(i, _)| i + 1)
            .collect()
    }

    /// The variable behind a value reference of the given base type, as the FMU's
    /// `fmi2Get*/fmi2Set*` receive it.
    pub fn find(&self, base_type: BaseType, value_reference: u32) -> Option<&ScalarVariable> {
        self.variables
            .iter()
            .find(|v| v.base_type() == base_type && v.value_reference == value_reference)
    }

    /// The variable with this name.
    pub fn by_name(&self, name: &str) -> Option<&ScalarVariable> {
        self.variables.iter().find(|v| v.name == name)
    }

    /// The enumeration type with this name.
    pub fn enumeration(&self, name: &str) -> Option<&EnumerationType> {
        self.enumerations.iter().find(|e| e.name == name)
    }

    /// The units of [`unit_definitions`] that some variable uses, in catalogue order.
    /// Only these are written, so adding a unit to the catalogue does not change the
    /// GUID of FMUs that do not use it.
    pub fn used_units(&self) -> Vec<Unit> {
        unit_definitions()
            .into_iter()
            .filter(|u| {
                self.variables.iter().any(|v| match &v.kind {
                    VarKind::Real { unit: Some(n), .. } => *n == u.name,
                    _ => false,
                })
            })
            .collect()
    }
}
