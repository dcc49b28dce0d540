use std::collections::BTreeMap;

use modeldesc::*;
use quick_xml::events::Event;
use quick_xml::{Reader, XmlVersion};

/// A small servovalve-like FMU: inputs, outputs, parameters and one enumeration.
/// ScalarVariable indices are given in the comments.
fn sample() -> ModelDescription {
    ModelDescription {
        model_name: "HydroBench.Sample".into(),
        model_identifier: "hydrobench_sample".into(),
        description: "Sample <valve> & \"actuator\"\nsecond line".into(),
        generation_tool: "HydroBench 0.1.0".into(),
        log_categories: vec![
            ("logStatusError".into(), "errors".into()),
            ("logAll".into(), "everything".into()),
        ],
        default_experiment: Some(DefaultExperiment {
            start_time: 0.0,
            stop_time: 0.5,
            tolerance: Some(1e-6),
            step_size: Some(1e-3),
        }),
        enumerations: vec![EnumerationType {
            name: "Mode".into(),
            description: "manifold mode".into(),
            items: vec![
                EnumItem {
                    name: "FourWay".into(),
                    value: 1,
                    description: "mode 1".into(),
                },
                EnumItem {
                    name: "TwoValves".into(),
                    value: 2,
                    description: "mode 2".into(),
                },
                EnumItem {
                    name: "ThreeWay".into(),
                    value: 3,
                    description: "mode 3".into(),
                },
            ],
        }],
        variables: vec![
            // 1
            ScalarVariable::enumeration_parameter("mode", 0, "manifold mode", "Mode", 3),
            // 2
            ScalarVariable::real_input("u1", 0, "valve 1 command", "V", 0.0)
                .with_real_range(-10.0, 10.0),
            // 3
            ScalarVariable::real_input("f_ext", 1, "external force", "N", 0.0),
            // 4
            ScalarVariable::real_tunable("Kp", 2, "proportional gain", "V/m", 1169.0)
                .with_display_unit("V/mm"),
            // 5: output, initial defaults to calculated -> initial unknown
            ScalarVariable::real_output("actuator.y", 3, "rod position", "m")
                .with_display_unit("mm"),
            // 6: output with initial exact -> not an initial unknown
            ScalarVariable::real_output("p_A", 4, "chamber A pressure", "Pa")
                .with_initial(Initial::Exact)
                .with_display_unit("bar")
                .with_start(1e5),
            // 7: calculated parameter -> initial unknown
            ScalarVariable::new(
                "omega_n",
                5,
                "hydraulic natural frequency",
                Causality::CalculatedParameter,
                Variability::Fixed,
                VarKind::Real {
                    start: None,
                    min: None,
                    max: None,
                    unit: Some("rad/s".into()),
                    display_unit: Some("Hz".into()),
                },
            ),
            // 8: output with initial approx -> initial unknown
            ScalarVariable::real_output("actuator.v", 6, "rod velocity", "m/s")
                .with_initial(Initial::Approx)
                .with_start(0.0),
            // 9
            ScalarVariable::boolean_parameter("effects.dry_friction", 0, "dry friction on", true),
            // 10: local, not in ModelStructure
            ScalarVariable::new(
                "x_spool",
                7,
                "spool position",
                Causality::Local,
                Variability::Continuous,
                VarKind::Real {
                    start: None,
                    min: None,
                    max: None,
                    unit: Some("m".into()),
                    display_unit: None,
                },
            ),
            // 11
            ScalarVariable::integer_parameter("sensor.delay_samples", 1, "sensor delay", 1)
                .with_integer_range(0, 10),
            // 12
            ScalarVariable::new(
                "label",
                0,
                "free text with <, &, ' and \"",
                Causality::Parameter,
                Variability::Fixed,
                VarKind::String {
                    start: Some("bench <A&B> \"x\"".into()),
                },
            ),
        ],
        output_dependencies: Default::default(),
    }
}

trait WithStart {
    fn with_start(self, x: f64) -> Self;
}

impl WithStart for ScalarVariable {
    fn with_start(mut self, x: f64) -> Self {
        if let VarKind::Real { start, .. } = &mut self.kind {
            *start = Some(x);
        }
        self
    }
}

/// One parsed element: path from the root, and its attributes (unescaped).
#[derive(Debug)]
struct Node {
    path: Vec<String>,
    attrs: BTreeMap<String, String>,
}

fn parse(xml: &str) -> Vec<Node> {
    let mut reader = Reader::from_str(xml);
    reader.config_mut().trim_text(true);
    let mut stack: Vec<String> = Vec::new();
    let mut nodes = Vec::new();
    let mut roots = 0;
    loop {
        let ev = reader.read_event().expect("well-formed XML");
        match ev {
            Event::Start(ref e) | Event::Empty(ref e) => {
                let name = e.name().as_ref().to_string();
                let mut attrs = BTreeMap::new();
                for a in e.attributes() {
                    let a = a.expect("well-formed attribute");
                    let key = a.key.as_ref().to_string();
                    let value = a.normalized_value(XmlVersion::Explicit1_0).unwrap();
                    assert!(
                        attrs.insert(key.clone(), value.into_owned()).is_none(),
                        "attribute {key} twice on {name}"
                    );
                }
                if stack.is_empty() {
                    roots += 1;
                }
                let mut path = stack.clone();
                path.push(name.clone());
                nodes.push(Node { path, attrs });
                if matches!(ev, Event::Start(_)) {
                    stack.push(name);
                }
            }
            Event::End(e) => {
                let name = e.name().as_ref().to_string();
                assert_eq!(stack.pop().as_deref(), Some(name.as_str()));
            }
            Event::Text(t) => panic!("unexpected text {t:?}"),
            Event::Eof => break,
            _ => {}
        }
    }
    assert!(stack.is_empty());
    assert_eq!(roots, 1);
    nodes
}

fn children<'a>(nodes: &'a [Node], parent: &[&str]) -> Vec<&'a Node> {
    nodes
        .iter()
        .filter(|n| n.path.len() == parent.len() + 1 && n.path[..parent.len()] == *parent)
        .collect()
}

fn child_names(nodes: &[Node], parent: &[&str]) -> Vec<String> {
    children(nodes, parent)
        .iter()
        .map(|n| n.path.last().unwrap().clone())
        .collect()
}

fn unknown_indices(nodes: &[Node], list: &str) -> Vec<usize> {
    children(nodes, &["fmiModelDescription", "ModelStructure", list])
        .iter()
        .map(|n| {
            assert_eq!(n.path.last().unwrap(), "Unknown");
            assert!(
                !n.attrs.contains_key("dependencies"),
                "dependencies must be omitted"
            );
            n.attrs["index"].parse().unwrap()
        })
        .collect()
}

const XSD_ORDER: [&str; 8] = [
    "CoSimulation",
    "UnitDefinitions",
    "TypeDefinitions",
    "LogCategories",
    "DefaultExperiment",
    "VendorAnnotations",
    "ModelVariables",
    "ModelStructure",
];

fn assert_xsd_order(names: &[String]) {
    let pos: Vec<usize> = names
        .iter()
        .map(|n| {
            XSD_ORDER
                .iter()
                .position(|x| x == n)
                .unwrap_or_else(|| panic!("unexpected element {n}"))
        })
        .collect();
    assert!(pos.windows(2).all(|w| w[0] < w[1]), "order {names:?}");
}

fn problems(md: &ModelDescription) -> Vec<String> {
    md.check().expect_err("check should fail")
}

fn assert_problem(md: &ModelDescription, needle: &str) {
    let p = problems(md);
    assert!(
        p.iter().any(|s| s.contains(needle)),
        "no problem mentioning {needle:?} in {p:#?}"
    );
}

#[test]
fn sample_passes_check() {
    assert_eq!(sample().check(), Ok(()));
}

#[test]
fn xml_parses_back_in_xsd_order() {
    let md = sample();
    let xml = md.to_xml();
    assert!(xml.starts_with("<?xml version=\"1.0\" encoding=\"UTF-8\"?>"));
    let nodes = parse(&xml);

    let root = &nodes[0];
    assert_eq!(root.path, ["fmiModelDescription"]);
    assert_eq!(root.attrs["fmiVersion"], "2.0");
    assert_eq!(root.attrs["modelName"], md.model_name);
    assert_eq!(root.attrs["guid"], md.guid());
    assert_eq!(
        root.attrs["description"], md.description,
        "escaping round trip"
    );
    assert_eq!(root.attrs["generationTool"], "HydroBench 0.1.0");
    assert_eq!(root.attrs["variableNamingConvention"], "structured");
    assert_eq!(root.attrs["numberOfEventIndicators"], "0");
    assert!(!root.attrs.contains_key("generationDateAndTime"));

    let top = child_names(&nodes, &["fmiModelDescription"]);
    assert_eq!(
        top,
        [
            "CoSimulation",
            "UnitDefinitions",
            "TypeDefinitions",
            "LogCategories",
            "DefaultExperiment",
            "ModelVariables",
            "ModelStructure"
        ]
    );
    assert_xsd_order(&top);

    let cs = &children(&nodes, &["fmiModelDescription"])[0].attrs;
    for (k, v) in [
        ("modelIdentifier", "hydrobench_sample"),
        ("canHandleVariableCommunicationStepSize", "true"),
        ("canGetAndSetFMUstate", "true"),
        ("canSerializeFMUstate", "true"),
        ("canInterpolateInputs", "false"),
        ("canBeInstantiatedOnlyOncePerProcess", "false"),
        ("canNotUseMemoryManagementFunctions", "true"),
    ] {
        assert_eq!(cs[k], v, "CoSimulation {k}");
    }

    // Only the units in use, each with its SI exponents and display units.
    let units = children(&nodes, &["fmiModelDescription", "UnitDefinitions"]);
    let unit_names: Vec<_> = units.iter().map(|u| u.attrs["name"].as_str()).collect();
    assert_eq!(unit_names, ["Pa", "m", "m/s", "N", "V", "V/m", "rad/s"]);
    let pa = children(&nodes, &["fmiModelDescription", "UnitDefinitions", "Unit"]);
    assert_eq!(pa[0].path.last().unwrap(), "BaseUnit");
    assert_eq!(
        (&pa[0].attrs["kg"], &pa[0].attrs["m"], &pa[0].attrs["s"]),
        (&"1".to_string(), &"-1".to_string(), &"-2".to_string())
    );
    assert!(!pa[0].attrs.contains_key("factor"));
    let bar = pa
        .iter()
        .find(|n| n.attrs.get("name").map(String::as_str) == Some("bar"));
    assert_eq!(bar.unwrap().attrs["factor"].parse::<f64>().unwrap(), 1e-5);

    let items = children(
        &nodes,
        &[
            "fmiModelDescription",
            "TypeDefinitions",
            "SimpleType",
            "Enumeration",
        ],
    );
    assert_eq!(items.len(), 3);
    assert_eq!(items[2].attrs["name"], "ThreeWay");
    assert_eq!(items[2].attrs["value"], "3");

    let vars = children(&nodes, &["fmiModelDescription", "ModelVariables"]);
    assert_eq!(vars.len(), md.variables.len());
    for (node, v) in vars.iter().zip(&md.variables) {
        assert_eq!(node.attrs["name"], v.name);
        assert_eq!(node.attrs["valueReference"], v.value_reference.to_string());
        assert_eq!(node.attrs["description"], v.description);
        assert_eq!(node.attrs["causality"], v.causality.as_str());
        assert_eq!(node.attrs["variability"], v.variability.as_str());
        assert_eq!(
            node.attrs.get("initial").map(String::as_str),
            v.initial.map(Initial::as_str)
        );
    }
    let type_elements: Vec<_> = nodes
        .iter()
        .filter(|n| n.path.len() == 4 && n.path[2] == "ScalarVariable")
        .collect();
    let kinds: Vec<_> = type_elements.iter().map(|n| n.path[3].as_str()).collect();
    assert_eq!(
        kinds,
        [
            "Enumeration",
            "Real",
            "Real",
            "Real",
            "Real",
            "Real",
            "Real",
            "Real",
            "Boolean",
            "Real",
            "Integer",
            "String"
        ]
    );
    let a = |i: usize| &type_elements[i].attrs;
    assert_eq!(a(0)["declaredType"], "Mode");
    assert_eq!(a(0)["start"], "3");
    assert_eq!(a(1)["min"], "-10");
    assert_eq!(a(1)["max"], "10");
    assert_eq!(a(1)["start"], "0");
    assert_eq!(a(1)["unit"], "V");
    assert_eq!(a(3)["start"], "1169");
    assert_eq!(a(3)["displayUnit"], "V/mm");
    assert!(
        !a(4).contains_key("start"),
        "calculated output has no start"
    );
    assert_eq!(a(5)["start"], "100000");
    assert_eq!(a(8)["start"], "true");
    assert_eq!(a(10)["min"], "0");
    assert_eq!(a(10)["start"], "1");
    assert_eq!(a(11)["start"], "bench <A&B> \"x\"");
}

#[test]
fn model_structure_indices() {
    let md = sample();
    assert_eq!(md.output_indices(), [5, 6, 8]);
    assert_eq!(md.initial_unknown_indices(), [5, 7, 8]);
    let nodes = parse(&md.to_xml());
    assert_eq!(
        child_names(&nodes, &["fmiModelDescription", "ModelStructure"]),
        ["Outputs", "InitialUnknowns"]
    );
    assert_eq!(unknown_indices(&nodes, "Outputs"), [5, 6, 8]);
    assert_eq!(unknown_indices(&nodes, "InitialUnknowns"), [5, 7, 8]);
}

#[test]
fn empty_containers_are_omitted() {
    let mut md = sample();
    md.enumerations.clear();
    md.log_categories.clear();
    md.default_experiment = None;
    // Keep only the inputs, parameters and the local: no outputs, no calculated parameters.
    md.variables.retain(|v| {
        matches!(
            v.causality,
            Causality::Input | Causality::Parameter | Causality::Local
        ) && !matches!(v.kind, VarKind::Enumeration { .. })
    });
    assert_eq!(md.check(), Ok(()));
    let nodes = parse(&md.to_xml());
    let top = child_names(&nodes, &["fmiModelDescription"]);
    assert_eq!(
        top,
        [
            "CoSimulation",
            "UnitDefinitions",
            "ModelVariables",
            "ModelStructure"
        ]
    );
    assert!(child_names(&nodes, &["fmiModelDescription", "ModelStructure"]).is_empty());

    // Outputs that are all initial="exact": Outputs present, InitialUnknowns absent.
    md.variables.push(
        ScalarVariable::real_output("q", 10, "flow", "m3/s")
            .with_initial(Initial::Exact)
            .with_start(0.0),
    );
    assert_eq!(md.check(), Ok(()));
    let nodes = parse(&md.to_xml());
    assert_eq!(
        child_names(&nodes, &["fmiModelDescription", "ModelStructure"]),
        ["Outputs"]
    );
    assert_eq!(unknown_indices(&nodes, "Outputs"), [md.variables.len()]);

    // No units at all: no UnitDefinitions.
    for v in &mut md.variables {
        if let VarKind::Real {
            unit, display_unit, ..
        } = &mut v.kind
        {
            *unit = None;
            *display_unit = None;
        }
    }
    let nodes = parse(&md.to_xml());
    assert_eq!(
        child_names(&nodes, &["fmiModelDescription"]),
        ["CoSimulation", "ModelVariables", "ModelStructure"]
    );
}

#[test]
fn guid_is_stable_and_tracks_content() {
    let md = sample();
    let g = md.guid();
    assert_eq!(g.len(), 38);
    assert!(g.starts_with('{') && g.ends_with('}'));
    let groups: Vec<_> = g[1..37].split('-').map(str::len).collect();
    assert_eq!(groups, [8, 4, 4, 4, 12]);
    assert!(g[1..37].chars().all(|c| c == '-' || c.is_ascii_hexdigit()));

    assert_eq!(sample().guid(), g);
    assert_eq!(md.to_xml(), sample().to_xml());

    let mut changed = sample();
    changed.variables[1].value_reference = 42;
    assert_ne!(changed.guid(), g);

    let mut changed = sample();
    if let VarKind::Real { start, .. } = &mut changed.variables[3].kind {
        *start = Some(1170.0);
    }
    assert_ne!(changed.guid(), g);

    let mut changed = sample();
    changed.variables[4].description.push('.');
    assert_ne!(changed.guid(), g);
}

#[test]
fn inputs_never_get_an_initial_attribute() {
    let mut md = sample();
    md.variables[1].initial = Some(Initial::Exact);
    assert_problem(
        &md,
        "initial=\"exact\" is not allowed for causality=\"input\"",
    );
    let nodes = parse(&md.to_xml());
    let vars = children(&nodes, &["fmiModelDescription", "ModelVariables"]);
    assert!(!vars[1].attrs.contains_key("initial"));
}

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
