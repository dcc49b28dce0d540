//! The XML the writer produces, parsed back: element order of the schema, model
//! structure indices, omitted empty containers, the GUID, and attributes never written.

use std::collections::BTreeMap;

use modeldesc::*;
use quick_xml::events::Event;
use quick_xml::{Reader, XmlVersion};

use super::{assert_problem, sample, WithStart};

/// One parsed element: path from the root, and its attributes (unescaped).
#[derive(Debug)]
pub(crate) struct Node {
    path: Vec<String>,
    attrs: BTreeMap<String, String>,
}

pub(crate) fn parse(xml: &str) -> Vec<Node> {
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
