//! FMI 2.0 rules beyond the XML schema (FMI 2.0.x section 2.2.7 and the schema's notes).

use std::collections::{HashMap, HashSet};

use crate::names::{is_c_identifier, is_structured_name};
use crate::units::unit_definitions;
use crate::{BaseType, Causality, Initial, ModelDescription, ScalarVariable, VarKind, Variability};

/// The standard's table of which `initial` values a causality/variability pair admits
/// (its cases A to D; the independent variable is treated like an input).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum InitialRule {
    /// Only exact, the default: parameters and constants.
    A,
    /// approx or calculated, default calculated: calculated parameters, fixed/tunable locals.
    B,
    /// exact, approx or calculated, default calculated: discrete/continuous outputs and locals.
    C,
    /// No initial attribute allowed: inputs and the independent variable.
    D,
}

impl InitialRule {
    pub(crate) fn allowed(self) -> &'static [Initial] {
        match self {
            InitialRule::A => &[Initial::Exact],
            InitialRule::B => &[Initial::Approx, Initial::Calculated],
            InitialRule::C => &[Initial::Exact, Initial::Approx, Initial::Calculated],
            InitialRule::D => &[],
        }
    }

    pub(crate) fn default(self) -> Option<Initial> {
        match self {
            InitialRule::A => Some(Initial::Exact),
            InitialRule::B | InitialRule::C => Some(Initial::Calculated),
            InitialRule::D => None,
        }
    }
}

/// `None` for the combinations the standard forbids (constant parameters, continuous
/// parameters, constant or tunable inputs, ...).
pub(crate) fn initial_rule(c: Causality, v: Variability) -> Option<InitialRule> {
    use Causality as C;
    use Variability as V;
    match (c, v) {
        (C::Parameter, V::Fixed | V::Tunable) => Some(InitialRule::A),
        (C::CalculatedParameter, V::Fixed | V::Tunable) => Some(InitialRule::B),
        (C::Input, V::Discrete | V::Continuous) => Some(InitialRule::D),
        (C::Output | C::Local, V::Constant) => Some(InitialRule::A),
        (C::Output, V::Discrete | V::Continuous) => Some(InitialRule::C),
        (C::Local, V::Fixed | V::Tunable) => Some(InitialRule::B),
        (C::Local, V::Discrete | V::Continuous) => Some(InitialRule::C),
        (C::Independent, V::Continuous) => Some(InitialRule::D),
        _ => None,
    }
}

/// Characters XML 1.0 cannot carry at all, not even as character references.
pub(crate) fn is_xml_char(c: char) -> bool {
    matches!(c, '\t' | '\n' | '\r') || (c >= ' ' && c != '\u{FFFE}' && c != '\u{FFFF}')
}

pub(crate) fn problems(md: &ModelDescription) -> Vec<String> {
    let mut p = Vec::new();
    check_header(md, &mut p);
    check_texts(md, &mut p);
    check_enumerations(md, &mut p);
    check_names_and_references(md, &mut p);
    for (output, inputs) in &md.output_dependencies {
        let is = |name: &str, c: Causality| {
            md.variables
                .iter()
                .any(|v| v.name == name && v.causality == c)
        };
        if !is(output, Causality::Output) {
            p.push(format!(
                "dependencies are declared for {output:?}, which is not an output"
            ));
        }
        for i in inputs {
            if !is(i, Causality::Input) {
                p.push(format!(
                    "output {output:?} depends on {i:?}, which is not an input"
                ));
            }
        }
    }
    let mut independents = 0;
    for v in &md.variables {
        check_variable(md, v, &mut p);
        if v.causality == Causality::Independent {
            independents += 1;
        }
    }
    if independents > 1 {
        p.push(format!(
            "{independents} variables have causality=\"independent\"; at most one may"
        ));
    }
    p
}

fn check_header(md: &ModelDescription, p: &mut Vec<String>) {
    if md.model_name.is_empty() {
        p.push("modelName is empty".into());
    }
    if !is_c_identifier(&md.model_identifier) {
        p.push(format!(
            "modelIdentifier \"{}\" is not a C identifier",
            md.model_identifier
        ));
    }
    if md.variables.is_empty() {
        p.push("ModelVariables is empty; FMI 2.0 requires at least one variable".into());
    }
    let mut seen = HashSet::new();
    for (name, _) in &md.log_categories {
        if name.is_empty() {
            p.push("a log category has an empty name".into());
        } else if !seen.insert(name.as_str()) {
            p.push(format!("log category \"{name}\" is declared twice"));
        }
    }
    if let Some(de) = &md.default_experiment {
        let mut finite = |what: &str, x: f64| {
            if !x.is_finite() {
                p.push(format!("DefaultExperiment {what} = {x} is not finite"));
            }
        };
        finite("startTime", de.start_time);
        finite("stopTime", de.stop_time);
        if let Some(t) = de.tolerance {
            finite("tolerance", t);
        }
        if let Some(h) = de.step_size {
            finite("stepSize", h);
        }
        if de.stop_time < de.start_time {
            p.push(format!(
                "DefaultExperiment stopTime {} is before startTime {}",
                de.stop_time, de.start_time
            ));
        }
        if de.tolerance.is_some_and(|t| t <= 0.0) {
            p.push("DefaultExperiment tolerance must be positive".into());
        }
        if de.step_size.is_some_and(|h| h <= 0.0) {
            p.push("DefaultExperiment stepSize must be positive".into());
        }
    }
}

/// Every string that ends up in the XML, with a label for the message.
fn check_texts(md: &ModelDescription, p: &mut Vec<String>) {
    let mut texts: Vec<(String, &str)> = vec![
        ("modelName".into(), &md.model_name),
        ("description".into(), &md.description),
        ("generationTool".into(), &md.generation_tool),
    ];
    for (n, d) in &md.log_categories {
        texts.push(("log category name".into(), n));
        texts.push((format!("description of log category \"{n}\""), d));
    }
    for e in &md.enumerations {
        texts.push(("enumeration type name".into(), &e.name));
        texts.push((
            format!("description of enumeration \"{}\"", e.name),
            &e.description,
        ));
        for i in &e.items {
            texts.push((format!("item name in enumeration \"{}\"", e.name), &i.name));
            texts.push((
                format!("description of item \"{}\"", i.name),
                &i.description,
            ));
        }
    }
    for v in &md.variables {
        texts.push(("variable name".into(), &v.name));
        texts.push((format!("description of \"{}\"", v.name), &v.description));
        match &v.kind {
            VarKind::String { start: Some(s) } => {
                texts.push((format!("start of \"{}\"", v.name), s));
            }
            VarKind::Enumeration { declared_type, .. } => {
                texts.push((format!("declaredType of \"{}\"", v.name), declared_type));
            }
            _ => {}
        }
    }
    for (what, s) in texts {
        if let Some(c) = s.chars().find(|&c| !is_xml_char(c)) {
            p.push(format!(
                "{what} contains U+{:04X}, which XML 1.0 cannot represent",
                c as u32
            ));
        }
    }
}

fn check_enumerations(md: &ModelDescription, p: &mut Vec<String>) {
    let mut types = HashSet::new();
    for e in &md.enumerations {
        if e.name.is_empty() {
            p.push("an enumeration type has an empty name".into());
        } else if !types.insert(e.name.as_str()) {
            p.push(format!("enumeration type \"{}\" is declared twice", e.name));
        }
        if md.variables.iter().any(|v| v.name == e.name) {
            p.push(format!(
                "enumeration type \"{}\" has the name of a variable; SimpleType names must differ from ScalarVariable names",
                e.name
            ));
        }
        if e.items.is_empty() {
            p.push(format!("enumeration type \"{}\" has no items", e.name));
        }
        let mut names = HashSet::new();
        let mut values = HashSet::new();
        for i in &e.items {
            if i.name.is_empty() {
                p.push(format!(
                    "enumeration \"{}\" has an item with an empty name",
                    e.name
                ));
            } else if !names.insert(i.name.as_str()) {
                p.push(format!(
                    "enumeration \"{}\" has item \"{}\" twice",
                    e.name, i.name
                ));
            }
            if !values.insert(i.value) {
                p.push(format!(
                    "enumeration \"{}\" uses value {} for more than one item",
                    e.name, i.value
                ));
            }
        }
    }
}

fn check_names_and_references(md: &ModelDescription, p: &mut Vec<String>) {
    let mut names: HashMap<&str, usize> = HashMap::new();
    let mut refs: HashMap<(BaseType, u32), &str> = HashMap::new();
    for (i, v) in md.variables.iter().enumerate() {
        if let Some(first) = names.insert(v.name.as_str(), i + 1) {
            p.push(format!(
                "variable name \"{}\" is used by variables {first} and {}",
                v.name,
                i + 1
            ));
        }
        if !is_structured_name(&v.name) {
            p.push(format!(
                "\"{}\" is not a legal name under variableNamingConvention=\"structured\"",
                v.name
            ));
        }
        // Aliases (shared references) would need identical values, which this crate does
        // not model, so a shared reference is always a bug in the declarations.
        let key = (v.base_type(), v.value_reference);
        if let Some(other) = refs.insert(key, &v.name) {
            p.push(format!(
                "\"{}\" and \"{other}\" share value reference {} of base type {:?}",
                v.name, v.value_reference, key.0
            ));
        }
    }
}

fn check_variable(md: &ModelDescription, v: &ScalarVariable, p: &mut Vec<String>) {
    let name = &v.name;
    let c = v.causality.as_str();
    let var = v.variability.as_str();

    if v.variability == Variability::Continuous && v.base_type() != BaseType::Real {
        p.push(format!(
            "\"{name}\" is {} and cannot have variability=\"continuous\"",
            v.kind.element_name()
        ));
    }
    if v.causality == Causality::Independent && !matches!(v.kind, VarKind::Real { .. }) {
        p.push(format!("independent variable \"{name}\" must be Real"));
    }

    let Some(rule) = initial_rule(v.causality, v.variability) else {
        p.push(format!(
            "\"{name}\": causality=\"{c}\" with variability=\"{var}\" is not allowed"
        ));
        // Start-value rules depend on a legal combination; checking them would only
        // repeat the same mistake in other words.
        check_values(md, v, p);
        return;
    };
    if let Some(init) = v.initial {
        if !rule.allowed().contains(&init) {
            let allowed: Vec<_> = rule.allowed().iter().map(|i| i.as_str()).collect();
            p.push(format!(
                "\"{name}\": initial=\"{}\" is not allowed for causality=\"{c}\", variability=\"{var}\" (allowed: {})",
                init.as_str(),
                if allowed.is_empty() { "none".to_string() } else { allowed.join(", ") }
            ));
        }
    }

    let initial = v.effective_initial();
    let has_start = v.kind.has_start();
    let needs_start = v.causality == Causality::Input
        || matches!(initial, Some(Initial::Exact | Initial::Approx));
    let forbids_start =
        v.causality == Causality::Independent || initial == Some(Initial::Calculated);
    if needs_start && !has_start {
        let why = if v.causality == Causality::Input {
            "it is an input".to_string()
        } else {
            format!("its initial is {}", initial.map_or("", Initial::as_str))
        };
        p.push(format!("\"{name}\" needs a start value because {why}"));
    }
    if forbids_start && has_start {
        let why = if v.causality == Causality::Independent {
            "it is the independent variable".to_string()
        } else if v.initial.is_some() {
            "its initial is calculated".to_string()
        } else {
            format!("its initial defaults to calculated for causality=\"{c}\", variability=\"{var}\"; set initial exact or approx to give one")
        };
        p.push(format!(
            "\"{name}\" must not have a start value because {why}"
        ));
    }
    check_values(md, v, p);
}

fn check_values(md: &ModelDescription, v: &ScalarVariable, p: &mut Vec<String>) {
    let name = &v.name;
    match &v.kind {
        VarKind::Real {
            start,
            min,
            max,
            unit,
            display_unit,
        } => {
            for (what, x) in [("start", start), ("min", min), ("max", max)] {
                if let Some(x) = x {
                    if !x.is_finite() {
                        p.push(format!("\"{name}\": {what} = {x} is not finite"));
                    }
                }
            }
            check_range(name, *min, *max, *start, p);
            check_units(v, unit.as_deref(), display_unit.as_deref(), p);
        }
        VarKind::Integer { start, min, max } => check_range(name, *min, *max, *start, p),
        VarKind::Enumeration {
            declared_type,
            start,
            min,
            max,
        } => {
            check_range(name, *min, *max, *start, p);
            match md.enumeration(declared_type) {
                None => p.push(format!(
                    "\"{name}\" has declaredType \"{declared_type}\", which TypeDefinitions does not define"
                )),
                Some(e) => {
                    if let Some(s) = start {
                        if e.item(*s).is_none() {
                            p.push(format!(
                                "\"{name}\": start {s} is not a value of enumeration \"{declared_type}\""
                            ));
                        }
                    }
                }
            }
        }
        VarKind::Boolean { .. } | VarKind::String { .. } => {}
    }
}

fn check_range<T: PartialOrd + std::fmt::Display + Copy>(
    name: &str,
    min: Option<T>,
    max: Option<T>,
    start: Option<T>,
    p: &mut Vec<String>,
) {
    if let (Some(lo), Some(hi)) = (min, max) {
        if lo > hi {
            p.push(format!("\"{name}\": min {lo} is greater than max {hi}"));
        }
    }
    if let Some(s) = start {
        if min.is_some_and(|lo| s < lo) {
            p.push(format!(
                "\"{name}\": start {s} is below min {}",
                min.unwrap()
            ));
        }
        if max.is_some_and(|hi| s > hi) {
            p.push(format!(
                "\"{name}\": start {s} is above max {}",
                max.unwrap()
            ));
        }
    }
}

fn check_units(
    v: &ScalarVariable,
    unit: Option<&str>,
    display_unit: Option<&str>,
    p: &mut Vec<String>,
) {
    let name = &v.name;
    let defined = unit_definitions();
    let found = unit.map(|u| (u, defined.iter().find(|d| d.name == u)));
    match (found, display_unit) {
        (Some((u, None)), _) => p.push(format!(
            "\"{name}\" has unit \"{u}\", which is not among the unit definitions"
        )),
        (Some((u, Some(def))), Some(du)) if def.display_unit(du).is_none() => p.push(format!(
            "\"{name}\" has displayUnit \"{du}\", which unit \"{u}\" does not define"
        )),
        (None, Some(du)) => p.push(format!("\"{name}\" has displayUnit \"{du}\" but no unit")),
        _ => {}
    }
}
