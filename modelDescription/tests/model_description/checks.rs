//! `ModelDescription::check`: each rule broken once, and the lookups it relies on.

use modeldesc::*;

use super::writer::parse;
use super::{assert_problem, sample, WithStart};

#[test]
fn check_catches_duplicate_name() {
    let mut md = sample();
    md.variables[2].name = "u1".into();
    assert_problem(&md, "variable name \"u1\" is used by variables 2 and 3");
}

#[test]
fn check_catches_duplicate_value_reference() {
    let mut md = sample();
    md.variables[2].value_reference = 0; // same as u1 (Real)
    assert_problem(&md, "share value reference 0 of base type Real");

    // Enumeration and Integer share fmi2GetInteger, so they clash too...
    let mut md = sample();
    md.variables[10].value_reference = 0; // Integer vs the Enumeration "mode"
    assert_problem(&md, "share value reference 0 of base type Integer");

    // ...but different base types may reuse a number (the sample already does).
    assert_eq!(sample().check(), Ok(()));
}

#[test]
fn check_catches_input_without_start() {
    let mut md = sample();
    if let VarKind::Real { start, .. } = &mut md.variables[2].kind {
        *start = None;
    }
    assert_problem(&md, "\"f_ext\" needs a start value because it is an input");
}

#[test]
fn check_catches_parameter_without_start() {
    let mut md = sample();
    md.variables[8].kind = VarKind::Boolean { start: None };
    assert_problem(
        &md,
        "\"effects.dry_friction\" needs a start value because its initial is exact",
    );
}

#[test]
fn check_catches_calculated_parameter_with_initial_exact() {
    let mut md = sample();
    md.variables[6].initial = Some(Initial::Exact);
    assert_problem(
        &md,
        "\"omega_n\": initial=\"exact\" is not allowed for causality=\"calculatedParameter\"",
    );
}

#[test]
fn check_catches_min_greater_than_max() {
    let mut md = sample();
    md.variables[1] = md.variables[1].clone().with_real_range(10.0, -10.0);
    assert_problem(&md, "\"u1\": min 10 is greater than max -10");

    let mut md = sample();
    md.variables[10] = md.variables[10].clone().with_integer_range(5, 10);
    assert_problem(&md, "\"sensor.delay_samples\": start 1 is below min 5");
}

#[test]
fn check_catches_unknown_unit() {
    let mut md = sample();
    md.variables[2] = ScalarVariable::real_input("f_ext", 1, "external force", "lbf", 0.0);
    assert_problem(&md, "unit \"lbf\", which is not among the unit definitions");

    let mut md = sample();
    md.variables[2] = md.variables[2].clone().with_display_unit("bar");
    assert_problem(&md, "displayUnit \"bar\", which unit \"N\" does not define");
}

#[test]
fn check_catches_unknown_enumeration_type() {
    let mut md = sample();
    md.variables[0] = ScalarVariable::enumeration_parameter("mode", 0, "", "Modes", 3);
    assert_problem(
        &md,
        "declaredType \"Modes\", which TypeDefinitions does not define",
    );

    let mut md = sample();
    md.variables[0] = ScalarVariable::enumeration_parameter("mode", 0, "", "Mode", 4);
    assert_problem(&md, "start 4 is not a value of enumeration \"Mode\"");
}

#[test]
fn check_catches_other_rule_breaks() {
    // Output with a start but initial defaulting to calculated.
    let mut md = sample();
    md.variables[4] = md.variables[4].clone().with_start(0.0);
    assert_problem(&md, "\"actuator.y\" must not have a start value");

    // Illegal causality/variability pairs.
    let mut md = sample();
    md.variables[3].variability = Variability::Continuous;
    assert_problem(
        &md,
        "causality=\"parameter\" with variability=\"continuous\" is not allowed",
    );
    let mut md = sample();
    md.variables[1].variability = Variability::Tunable;
    assert_problem(
        &md,
        "causality=\"input\" with variability=\"tunable\" is not allowed",
    );

    // Continuous Boolean.
    let mut md = sample();
    md.variables[8].causality = Causality::Local;
    md.variables[8].variability = Variability::Continuous;
    assert_problem(&md, "is Boolean and cannot have variability=\"continuous\"");

    // Names outside the structured convention; bad model identifier.
    let mut md = sample();
    md.variables[2].name = "f ext".into();
    md.model_identifier = "hydrobench-sample".into();
    assert_problem(&md, "\"f ext\" is not a legal name");
    assert_problem(
        &md,
        "modelIdentifier \"hydrobench-sample\" is not a C identifier",
    );

    // Infinite bounds and a control character in a description.
    let mut md = sample();
    md.variables[1] = md.variables[1]
        .clone()
        .with_real_range(f64::NEG_INFINITY, 10.0);
    md.variables[2].description = "bell\u{7}".into();
    assert_problem(&md, "\"u1\": min = -inf is not finite");
    assert_problem(&md, "contains U+0007");
    let xml = md.to_xml();
    assert!(!xml.contains("inf"), "infinities must never be written");
    parse(&xml);

    // Enumeration type sharing a variable's name; duplicate item values.
    let mut md = sample();
    md.enumerations[0].name = "mode".into();
    for v in &mut md.variables {
        if let VarKind::Enumeration { declared_type, .. } = &mut v.kind {
            *declared_type = "mode".into();
        }
    }
    md.enumerations[0].items[1].value = 1;
    assert_problem(&md, "has the name of a variable");
    assert_problem(&md, "uses value 1 for more than one item");

    // Two independent variables, one of them not Real.
    let mut md = sample();
    md.variables.push(ScalarVariable::new(
        "time",
        20,
        "",
        Causality::Independent,
        Variability::Continuous,
        VarKind::Real {
            start: None,
            min: None,
            max: None,
            unit: Some("s".into()),
            display_unit: None,
        },
    ));
    assert_eq!(md.check(), Ok(()));
    md.variables.push(ScalarVariable::new(
        "tick",
        20,
        "",
        Causality::Independent,
        Variability::Continuous,
        VarKind::Integer {
            start: None,
            min: None,
            max: None,
        },
    ));
    assert_problem(&md, "2 variables have causality=\"independent\"");
    assert_problem(&md, "independent variable \"tick\" must be Real");
}

#[test]
fn effective_initial_follows_the_standard_table() {
    use Causality as C;
    use Initial as I;
    use Variability as V;
    let real = |c, v| {
        ScalarVariable::new(
            "x",
            0,
            "",
            c,
            v,
            VarKind::Real {
                start: None,
                min: None,
                max: None,
                unit: None,
                display_unit: None,
            },
        )
        .effective_initial()
    };
    assert_eq!(real(C::Parameter, V::Fixed), Some(I::Exact));
    assert_eq!(real(C::Parameter, V::Tunable), Some(I::Exact));
    assert_eq!(real(C::CalculatedParameter, V::Fixed), Some(I::Calculated));
    assert_eq!(real(C::Local, V::Tunable), Some(I::Calculated));
    assert_eq!(real(C::Output, V::Constant), Some(I::Exact));
    assert_eq!(real(C::Local, V::Constant), Some(I::Exact));
    assert_eq!(real(C::Output, V::Continuous), Some(I::Calculated));
    assert_eq!(real(C::Local, V::Discrete), Some(I::Calculated));
    assert_eq!(real(C::Input, V::Continuous), None);
    assert_eq!(real(C::Independent, V::Continuous), None);
    assert_eq!(real(C::Parameter, V::Constant), None, "illegal pair");
}

#[test]
fn find_by_base_type_and_value_reference() {
    let md = sample();
    assert_eq!(md.find(BaseType::Real, 3).unwrap().name, "actuator.y");
    assert_eq!(md.find(BaseType::Integer, 0).unwrap().name, "mode");
    assert_eq!(
        md.find(BaseType::Integer, 1).unwrap().name,
        "sensor.delay_samples"
    );
    assert_eq!(
        md.find(BaseType::Boolean, 0).unwrap().name,
        "effects.dry_friction"
    );
    assert_eq!(md.find(BaseType::String, 0).unwrap().name, "label");
    assert!(md.find(BaseType::Boolean, 1).is_none());
    assert_eq!(md.by_name("Kp").unwrap().value_reference, 2);
}
