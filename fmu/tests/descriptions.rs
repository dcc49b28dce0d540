//! Every FMU's model description obeys the FMI 2.0 rules the crate checks.

#[test]
fn every_model_description_passes_the_fmi_rules() {
    let all = hbfmu::models::specs();
    assert_eq!(all.len(), 7);
    for spec in all {
        let (id, d, guid) = (spec.id, &spec.description, &spec.guid);
        if let Err(problems) = d.check() {
            panic!("{id}: {problems:#?}");
        }
        assert_eq!(&d.guid(), guid);
        assert!(d.to_xml().contains(&format!("modelIdentifier=\"{id}\"")));
    }
}

#[test]
fn guids_differ_between_models() {
    let all = hbfmu::models::specs();
    let mut guids: Vec<_> = all.iter().map(|s| s.guid.clone()).collect();
    guids.sort();
    guids.dedup();
    assert_eq!(guids.len(), all.len());
}

#[test]
fn documentation_lists_every_variable_and_parameter_files_load() {
    for spec in hbfmu::models::specs() {
        for v in &spec.description.variables {
            assert!(
                spec.documentation
                    .contains(&format!("<code>{}</code>", v.name)),
                "{}: {}",
                spec.id,
                v.name
            );
        }
        if let Some(text) = &spec.parameters {
            hbmodel::Params::from_toml_named(text, "parameters.toml").unwrap();
        }
    }
}
