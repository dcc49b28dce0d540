//! Every FMU's model description obeys the FMI 2.0 rules the crate checks.

#[test]
fn every_model_description_passes_the_fmi_rules() {
    let all = hbfmu::models::descriptions();
    assert_eq!(all.len(), 5);
    for (id, d, guid) in all {
        if let Err(problems) = d.check() {
            panic!("{id}: {problems:#?}");
        }
        assert_eq!(&d.guid(), guid);
        assert!(d.to_xml().contains(&format!("modelIdentifier=\"{id}\"")));
    }
}

#[test]
fn guids_differ_between_models() {
    let all = hbfmu::models::descriptions();
    let mut guids: Vec<_> = all.iter().map(|(_, _, g)| g.clone()).collect();
    guids.sort();
    guids.dedup();
    assert_eq!(guids.len(), all.len());
}
