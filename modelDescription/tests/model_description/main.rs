//! The model-description writer and its rule checks, on a small servovalve-like FMU:
//! `writer` parses the XML back and checks it against the FMI 2.0 schema's order and
//! indices; `checks` breaks one rule at a time and expects `check` to name it.

mod checks;
mod writer;

use modeldesc::*;

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
