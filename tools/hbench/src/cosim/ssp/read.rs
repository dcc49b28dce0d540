//! Reading an SSP package back: the SSD subset [`super::write`] produces.

use std::collections::BTreeMap;
use std::io::{Read, Seek};

use hbfmu::slave::Value;
use quick_xml::events::Event;

use super::{Component, Connection, End, System, SSD};

fn attr(e: &quick_xml::events::BytesStart, key: &str) -> Result<Option<String>, String> {
    for a in e.attributes() {
        let a = a.map_err(|e| e.to_string())?;
        if a.key.local_name().as_ref() == key {
            let v = a
                .normalized_value(quick_xml::XmlVersion::Implicit1_0)
                .map_err(|e| e.to_string())?;
            return Ok(Some(v.into_owned()));
        }
    }
    Ok(None)
}

fn parse_value(kind: &str, text: &str) -> Result<Value, String> {
    let bad = |e: &dyn std::fmt::Display| format!("bad parameter value {text:?}: {e}");
    Ok(match kind {
        "Real" => Value::Real(text.parse().map_err(|e| bad(&e))?),
        "Integer" | "Enumeration" => Value::Integer(text.parse().map_err(|e| bad(&e))?),
        _ => Value::Boolean(matches!(text, "true" | "1")),
    })
}

/// Parse a SystemStructure.ssd (the subset [`System`] holds; nested systems, signal
/// dictionaries and parameter mappings are refused or ignored).
pub fn parse_ssd(text: &str) -> Result<System, String> {
    let mut reader = quick_xml::Reader::from_str(text);
    let mut sys = System {
        name: String::new(),
        inputs: vec![],
        outputs: vec![],
        components: vec![],
        connections: vec![],
    };
    let mut depth_system = 0usize;
    let mut current: Option<Component> = None;
    let mut param: Option<String> = None;
    loop {
        let ev = reader.read_event().map_err(|e| format!("{SSD}: {e}"))?;
        let (e, empty) = match &ev {
            Event::Start(e) => (e.clone(), false),
            Event::Empty(e) => (e.clone(), true),
            Event::End(e) => {
                match e.local_name().as_ref() {
                    "Component" => sys.components.extend(current.take()),
                    "Parameter" => param = None,
                    "System" => depth_system -= 1,
                    _ => {}
                }
                continue;
            }
            Event::Eof => break,
            _ => continue,
        };
        match e.local_name().as_ref() {
            "SystemStructureDescription" => {
                sys.name = attr(&e, "name")?.unwrap_or_default();
            }
            "System" => {
                if depth_system > 0 {
                    return Err(format!("{SSD}: nested systems are not supported"));
                }
                if !empty {
                    depth_system += 1;
                }
            }
            "Component" => {
                let name = attr(&e, "name")?.ok_or("a Component without a name")?;
                let source = attr(&e, "source")?.ok_or("a Component without a source")?;
                let c = Component {
                    name,
                    source,
                    inputs: vec![],
                    outputs: vec![],
                    parameters: vec![],
                };
                if empty {
                    sys.components.push(c);
                } else {
                    current = Some(c);
                }
            }
            "Connector" => {
                let name = attr(&e, "name")?.ok_or("a Connector without a name")?;
                let kind = attr(&e, "kind")?.unwrap_or_default();
                let (ins, outs) = match current.as_mut() {
                    Some(c) => (&mut c.inputs, &mut c.outputs),
                    None => (&mut sys.inputs, &mut sys.outputs),
                };
                match kind.as_str() {
                    "input" => ins.push(name),
                    "output" => outs.push(name),
                    _ => {}
                }
            }
            "Parameter" => param = attr(&e, "name")?,
            k @ ("Real" | "Integer" | "Boolean" | "Enumeration") => {
                if let (Some(p), Some(c)) = (&param, current.as_mut()) {
                    let v = attr(&e, "value")?.ok_or("a parameter without a value")?;
                    c.parameters.push((p.clone(), parse_value(k, &v)?));
                }
            }
            "ParameterBinding" if attr(&e, "source")?.is_some() => {
                return Err(format!(
                    "{SSD}: parameter bindings from files are not supported; bind inline"
                ));
            }
            "Connection" => {
                let end = |w: &str| -> Result<End, String> {
                    Ok(End {
                        element: attr(&e, &format!("{w}Element"))?,
                        connector: attr(&e, &format!("{w}Connector"))?
                            .ok_or("a Connection without a connector")?,
                    })
                };
                sys.connections.push(Connection {
                    start: end("start")?,
                    end: end("end")?,
                });
            }
            _ => {}
        }
    }
    Ok(sys)
}

/// An opened SSP package: its system and the bytes of the FMUs it holds.
pub struct Package {
    pub system: System,
    pub fmus: BTreeMap<String, Vec<u8>>,
}

pub fn open<R: Read + Seek>(reader: R) -> Result<Package, String> {
    open_variant(reader, SSD)
}

/// Open the package with the system of its root SSD `ssd` (a variant, or [`SSD`]).
pub fn open_variant<R: Read + Seek>(reader: R, ssd: &str) -> Result<Package, String> {
    let mut zip = zip::ZipArchive::new(reader).map_err(|e| format!("not an SSP package: {e}"))?;
    let mut read = |name: &str| -> Result<Vec<u8>, String> {
        let mut f = zip
            .by_name(name)
            .map_err(|e| format!("{name} is missing from the package: {e}"))?;
        let mut v = Vec::new();
        f.read_to_end(&mut v).map_err(|e| e.to_string())?;
        Ok(v)
    };
    let ssd = String::from_utf8(read(ssd)?).map_err(|e| format!("{ssd}: {e}"))?;
    let system = parse_ssd(&ssd)?;
    let mut fmus = BTreeMap::new();
    for c in &system.components {
        if !fmus.contains_key(&c.source) {
            fmus.insert(c.source.clone(), read(&c.source)?);
        }
    }
    Ok(Package { system, fmus })
}
