//! modelDescription.xml rendering and the content-derived GUID.

use std::borrow::Cow;

use quick_xml::events::{BytesDecl, BytesEnd, BytesStart, BytesText, Event};
use quick_xml::Writer;
use sha2::{Digest, Sha256};

use crate::check::is_xml_char;
use crate::{Causality, ModelDescription, ScalarVariable, VarKind};

/// A real number in a form that reads back to the same f64 and that `xs:double` accepts.
/// `None` for NaN and infinities, which must never reach the file (`xs:double` would
/// accept `INF`/`NaN` but C importers parse these attributes with strtod-like code that
/// does not).
pub(crate) fn real(x: f64) -> Option<String> {
    if !x.is_finite() {
        return None;
    }
    let a = x.abs();
    // Display is shortest round-trip but never uses an exponent, so 1e-300 would be
    // 300 digits long; LowerExp is shortest round-trip too and gives e.g. "1e-14".
    Some(if a == 0.0 || (1e-5..1e16).contains(&a) {
        format!("{x}")
    } else {
        format!("{x:e}")
    })
}

/// The text with characters XML 1.0 cannot hold replaced by U+FFFD; quick-xml escapes
/// the rest (including newlines and tabs in attributes, so they survive normalisation).
fn text(s: &str) -> Cow<'_, str> {
    if s.chars().all(is_xml_char) {
        Cow::Borrowed(s)
    } else {
        Cow::Owned(
            s.chars()
                .map(|c| if is_xml_char(c) { c } else { '\u{FFFD}' })
                .collect(),
        )
    }
}

/// An element being built: attributes are added only when they have a value.
struct El(BytesStart<'static>);

impl El {
    fn new(name: &'static str) -> Self {
        El(BytesStart::new(name))
    }

    fn attr(mut self, key: &str, value: &str) -> Self {
        self.0.push_attribute((key, text(value).as_ref()));
        self
    }

    /// Empty strings are left out: every optional text attribute here means "unknown"
    /// when empty, and omitting it keeps the file quiet.
    fn attr_nonempty(self, key: &str, value: &str) -> Self {
        if value.is_empty() {
            self
        } else {
            self.attr(key, value)
        }
    }

    fn attr_opt<T: ToString>(self, key: &str, value: Option<T>) -> Self {
        match value {
            Some(v) => self.attr(key, &v.to_string()),
            None => self,
        }
    }

    fn real_opt(self, key: &str, value: Option<f64>) -> Self {
        let v = value.and_then(real);
        self.attr_opt(key, v)
    }
}

struct Out(Writer<Vec<u8>>);

impl Out {
    // Writing into a Vec cannot fail, so the io::Result is noise here.
    fn ev(&mut self, e: Event<'_>) {
        self.0
            .write_event(e)
            .expect("writing XML into memory cannot fail");
    }

    fn empty(&mut self, el: El) {
        self.ev(Event::Empty(el.0));
    }

    fn start(&mut self, el: El) {
        self.ev(Event::Start(el.0));
    }

    fn end(&mut self, name: &str) {
        self.ev(Event::End(BytesEnd::new(name)));
    }

    fn comment(&mut self, s: &str) {
        self.ev(Event::Comment(BytesText::from_escaped(s)));
    }
}

pub(crate) fn render(md: &ModelDescription, guid: &str) -> String {
    let mut out = Out(Writer::new_with_indent(Vec::new(), b' ', 2));
    out.ev(Event::Decl(BytesDecl::new("1.0", Some("UTF-8"), None)));

    // No generationDateAndTime: the GUID hashes this text and must not depend on the clock.
    out.start(
        El::new("fmiModelDescription")
            .attr("fmiVersion", "2.0")
            .attr("modelName", &md.model_name)
            .attr("guid", guid)
            .attr_nonempty("description", &md.description)
            .attr_nonempty("generationTool", &md.generation_tool)
            .attr("variableNamingConvention", "structured")
            .attr("numberOfEventIndicators", "0"),
    );

    out.empty(
        El::new("CoSimulation")
            .attr("modelIdentifier", &md.model_identifier)
            .attr("canHandleVariableCommunicationStepSize", "true")
            .attr("canGetAndSetFMUstate", "true")
            .attr("canSerializeFMUstate", "true")
            .attr("canInterpolateInputs", "false")
            .attr("canBeInstantiatedOnlyOncePerProcess", "false")
            .attr("canNotUseMemoryManagementFunctions", "true"),
    );

    // From here on every container is written only when it has children: the schema
    // requires at least one child in each of them.
    let units = md.used_units();
    if !units.is_empty() {
        out.start(El::new("UnitDefinitions"));
        for u in &units {
            out.start(El::new("Unit").attr("name", &u.name));
            let b = &u.base_unit;
            let mut base = El::new("BaseUnit");
            for (key, exp) in b.exponents() {
                base = base.attr_opt(key, (exp != 0).then_some(exp));
            }
            base = base
                .real_opt("factor", (b.factor != 1.0).then_some(b.factor))
                .real_opt("offset", (b.offset != 0.0).then_some(b.offset));
            out.empty(base);
            for d in &u.display_units {
                out.empty(
                    El::new("DisplayUnit")
                        .attr("name", &d.name)
                        .real_opt("factor", (d.factor != 1.0).then_some(d.factor))
                        .real_opt("offset", (d.offset != 0.0).then_some(d.offset)),
                );
            }
            out.end("Unit");
        }
        out.end("UnitDefinitions");
    }

    if !md.enumerations.is_empty() {
        out.start(El::new("TypeDefinitions"));
        for e in &md.enumerations {
            out.start(
                El::new("SimpleType")
                    .attr("name", &e.name)
                    .attr_nonempty("description", &e.description),
            );
            out.start(El::new("Enumeration"));
            for i in &e.items {
                out.empty(
                    El::new("Item")
                        .attr("name", &i.name)
                        .attr("value", &i.value.to_string())
                        .attr_nonempty("description", &i.description),
                );
            }
            out.end("Enumeration");
            out.end("SimpleType");
        }
        out.end("TypeDefinitions");
    }

    if !md.log_categories.is_empty() {
        out.start(El::new("LogCategories"));
        for (name, description) in &md.log_categories {
            out.empty(
                El::new("Category")
                    .attr("name", name)
                    .attr_nonempty("description", description),
            );
        }
        out.end("LogCategories");
    }

    if let Some(de) = &md.default_experiment {
        out.empty(
            El::new("DefaultExperiment")
                .real_opt("startTime", Some(de.start_time))
                .real_opt("stopTime", Some(de.stop_time))
                .real_opt("tolerance", de.tolerance)
                .real_opt("stepSize", de.step_size),
        );
    }

    out.start(El::new("ModelVariables"));
    for (i, v) in md.variables.iter().enumerate() {
        // The index comments make ModelStructure readable by eye.
        out.comment(&format!(" {} ", i + 1));
        write_variable(&mut out, v);
    }
    out.end("ModelVariables");

    out.start(El::new("ModelStructure"));
    let outputs = md.output_indices();
    if !outputs.is_empty() {
        out.start(El::new("Outputs"));
        for i in outputs {
            let mut el = El::new("Unknown").attr("index", &i.to_string());
            if let Some(deps) = md.dependency_indices(&md.variables[i - 1].name) {
                let list: Vec<String> = deps.iter().map(|d| d.to_string()).collect();
                el = el.attr("dependencies", &list.join(" "));
            }
            out.empty(el);
        }
        out.end("Outputs");
    }
    let unknowns = md.initial_unknown_indices();
    if !unknowns.is_empty() {
        out.start(El::new("InitialUnknowns"));
        for i in unknowns {
            out.empty(El::new("Unknown").attr("index", &i.to_string()));
        }
        out.end("InitialUnknowns");
    }
    out.end("ModelStructure");

    out.end("fmiModelDescription");
    let mut xml = String::from_utf8(out.0.into_inner()).expect("quick-xml writes UTF-8");
    xml.push('\n');
    xml
}

fn write_variable(out: &mut Out, v: &ScalarVariable) {
    // Inputs and the independent variable must not carry `initial` at all (fmpy and the
    // standard both reject it), whatever the declaration says; check() reports it.
    let initial = match v.causality {
        Causality::Input | Causality::Independent => None,
        _ => v.initial.map(|i| i.as_str()),
    };
    out.start(
        El::new("ScalarVariable")
            .attr("name", &v.name)
            .attr("valueReference", &v.value_reference.to_string())
            .attr_nonempty("description", &v.description)
            .attr("causality", v.causality.as_str())
            .attr("variability", v.variability.as_str())
            .attr_opt("initial", initial),
    );
    let el = El::new(v.kind.element_name());
    let el = match &v.kind {
        VarKind::Real {
            start,
            min,
            max,
            unit,
            display_unit,
        } => el
            .attr_opt("unit", unit.as_deref())
            .attr_opt("displayUnit", display_unit.as_deref())
            .real_opt("min", *min)
            .real_opt("max", *max)
            .real_opt("start", *start),
        VarKind::Integer { start, min, max } => el
            .attr_opt("min", *min)
            .attr_opt("max", *max)
            .attr_opt("start", *start),
        VarKind::Boolean { start } => el.attr_opt("start", *start),
        VarKind::Enumeration {
            declared_type,
            start,
            min,
            max,
        } => el
            .attr("declaredType", declared_type)
            .attr_opt("min", *min)
            .attr_opt("max", *max)
            .attr_opt("start", *start),
        VarKind::String { start } => el.attr_opt("start", start.as_deref()),
    };
    out.empty(el);
    out.end("ScalarVariable");
}

/// `{8-4-4-4-12}` hex of the first 128 bits of the SHA-256 of `xml`.
pub(crate) fn guid_of(xml: &str) -> String {
    let h = Sha256::digest(xml.as_bytes());
    let hex: String = h[..16].iter().map(|b| format!("{b:02x}")).collect();
    format!(
        "{{{}-{}-{}-{}-{}}}",
        &hex[0..8],
        &hex[8..12],
        &hex[12..16],
        &hex[16..20],
        &hex[20..32]
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reals_round_trip_in_xsd_double_form() {
        for x in [
            0.0,
            -0.0,
            1.0,
            -2.5,
            0.1,
            1e-5,
            9.99e-6,
            1e-14,
            1.234_567_890_123_456_7e-300,
            5e-324,
            1e15,
            1e16,
            123_456_789.012_345_6,
            f64::MAX,
            f64::MIN_POSITIVE,
            -273.15,
            60_000.0,
            1.0 / 3.0,
        ] {
            let s = real(x).unwrap();
            assert_eq!(
                s.parse::<f64>().unwrap().to_bits(),
                x.to_bits(),
                "{x} -> {s}"
            );
            // xs:double lexical form (no INF/NaN): sign, digits, optional fraction, optional exponent.
            let (mantissa, exp) = s.split_once('e').unwrap_or((&s, "0"));
            let mantissa = mantissa.strip_prefix('-').unwrap_or(mantissa);
            let exp = exp.strip_prefix('-').unwrap_or(exp);
            assert!(
                mantissa.chars().all(|c| c.is_ascii_digit() || c == '.')
                    && mantissa.chars().filter(|&c| c == '.').count() <= 1
                    && mantissa.chars().any(|c| c.is_ascii_digit())
                    && !exp.is_empty()
                    && exp.chars().all(|c| c.is_ascii_digit()),
                "{x} -> {s} is not an xs:double"
            );
            assert!(s.len() <= 24, "{x} -> {s} is needlessly long");
        }
        assert_eq!(real(1e-14).unwrap(), "1e-14");
        assert_eq!(real(1e-5).unwrap(), "0.00001");
        assert_eq!(real(f64::INFINITY), None);
        assert_eq!(real(f64::NEG_INFINITY), None);
        assert_eq!(real(f64::NAN), None);
    }

    #[test]
    fn guid_format() {
        let g = guid_of("abc");
        // SHA-256("abc") starts ba7816bf 8f01cfea 414140de 5dae2223 (FIPS 180-2 example).
        assert_eq!(g, "{ba7816bf-8f01-cfea-4141-40de5dae2223}");
    }
}
