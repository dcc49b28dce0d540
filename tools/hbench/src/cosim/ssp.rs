//! `bench.ssp`: the bench as a system of component FMUs, written as an SSP 1.0 package
//! (SystemStructure.ssd, the FMUs under resources/, one parameter set per working mode),
//! and read back by the `hbench cosim` master.
//!
//! The parameter bindings are derived, not typed: each component model is given the
//! whole-bench parameter tree of `bench.fmu` (`Params::thesis_bench(mode)`) and every
//! FMU parameter whose value then differs from the component's own default is bound.
//! So the system of components and `bench.fmu` describe the same physics by
//! construction, and a change of the thesis defaults reaches both.

use std::collections::BTreeMap;
use std::io::{Read, Seek, Write};
use std::path::Path;

use hbfmu::models::{actuator, controller, manifold, servovalve, HasParams};
use hbfmu::slave::{Model, Value};
use hbmodel::manifold::Circuit;
use hbmodel::{Mode, Params};
use quick_xml::events::Event;
use zip::write::SimpleFileOptions;

/// Name of the system description inside an SSP package (SSP 1.0, section 3).
pub const SSD: &str = "SystemStructure.ssd";

/// Mode bound in SystemStructure.ssd; the parameter sets of all three ship beside it.
pub const DEFAULT_MODE: Mode = Mode::ThreeWay;

const NS_SSD: &str = "http://ssp-standard.org/SSP1/SystemStructureDescription";
const NS_SSC: &str = "http://ssp-standard.org/SSP1/SystemStructureCommon";
const NS_SSV: &str = "http://ssp-standard.org/SSP1/SystemStructureParameterValues";

/// One component of the system: an instance of a packaged FMU.
#[derive(Debug, Clone, PartialEq)]
pub struct Component {
    pub name: String,
    /// Path of the FMU inside the package.
    pub source: String,
    pub inputs: Vec<String>,
    pub outputs: Vec<String>,
    /// Parameter name and value, in binding order.
    pub parameters: Vec<(String, Value)>,
}

/// A connector end: `element` None is the system's own connector.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct End {
    pub element: Option<String>,
    pub connector: String,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Connection {
    pub start: End,
    pub end: End,
}

/// The system a SystemStructure.ssd describes (the subset HydroBench writes and reads:
/// FMU components, Real connectors, connections, inline parameter values).
#[derive(Debug, Clone, PartialEq)]
pub struct System {
    pub name: String,
    pub inputs: Vec<String>,
    pub outputs: Vec<String>,
    pub components: Vec<Component>,
    pub connections: Vec<Connection>,
}

#[cfg(test)]
impl System {
    pub fn component(&self, name: &str) -> Option<&Component> {
        self.components.iter().find(|c| c.name == name)
    }
}

// ---------------------------------------------------------------------------------------
// The bench's system: components, wiring, bindings

/// Port wiring (DESIGN.md, port causality): valves take port pressures and give flows;
/// the manifold takes valve flows and chamber pressures and gives port pressures and
/// chamber flows; the actuator takes chamber flows and gives pressures and motion. The
/// same in every mode: the mode only changes what the manifold joins inside (mode 1:
/// SV2 stays connected at null; mode 3: the B ports drain to tank through the reducers).
const WIRES: [(&str, &str, &str, &str); 16] = [
    ("sv1", "Q_A", "manifold", "Q_A1"),
    ("sv1", "Q_B", "manifold", "Q_B1"),
    ("sv2", "Q_A", "manifold", "Q_A2"),
    ("sv2", "Q_B", "manifold", "Q_B2"),
    // the valves' flow sensitivities: the manifold's solver closes the stiff loop of
    // each valve orifice with its small port volume implicitly (docs/cosim.md)
    ("sv1", "dQ_A_dP_A", "manifold", "dQ_A1_dP_A1"),
    ("sv1", "dQ_B_dP_B", "manifold", "dQ_B1_dP_B1"),
    ("sv2", "dQ_A_dP_A", "manifold", "dQ_A2_dP_A2"),
    ("sv2", "dQ_B_dP_B", "manifold", "dQ_B2_dP_B2"),
    ("manifold", "P_A1", "sv1", "P_A"),
    ("manifold", "P_B1", "sv1", "P_B"),
    ("manifold", "P_A2", "sv2", "P_A"),
    ("manifold", "P_B2", "sv2", "P_B"),
    ("manifold", "Q1", "actuator", "Q1"),
    ("manifold", "Q2", "actuator", "Q2"),
    ("actuator", "P1", "manifold", "P1"),
    ("actuator", "P2", "manifold", "P2"),
    // + the chamber port's terms, same name at both ends (bench_system adds them)
];

/// System inputs and the component inputs they drive.
const SYSTEM_INPUTS: [(&str, &str, &str); 3] = [
    ("u1", "sv1", "u"),
    ("u2", "sv2", "u"),
    ("F_ext", "actuator", "F_ext"),
];

/// System outputs and the component outputs behind them.
const SYSTEM_OUTPUTS: [(&str, &str, &str); 7] = [
    ("y", "actuator", "y"),
    ("v", "actuator", "v"),
    ("a", "actuator", "a"),
    ("P1", "actuator", "P1"),
    ("P2", "actuator", "P2"),
    ("x_s1", "sv1", "x_s"),
    ("x_s2", "sv2", "x_s"),
];

/// Every parameter of model M whose value under `params` differs from M's default.
fn bindings<M: Model + HasParams>(params: &Params) -> Result<Vec<(String, Value)>, String> {
    let fresh = M::instantiate(None)?;
    let mut bound = M::instantiate(None)?;
    *bound.params_mut() = params.clone();
    Ok(M::variables()
        .into_iter()
        .filter(|v| v.decl.causality == modeldesc::Causality::Parameter)
        .filter_map(|v| {
            let (a, b) = ((v.get)(&fresh), (v.get)(&bound));
            (a != b).then(|| (v.decl.name.clone(), b))
        })
        .collect())
}

fn names<M: Model>(causality: modeldesc::Causality) -> Vec<String> {
    M::variables()
        .into_iter()
        .filter(|v| v.decl.causality == causality)
        .map(|v| v.decl.name)
        .collect()
}

fn component<M: Model + HasParams>(
    name: &str,
    fmu: &str,
    params: &Params,
) -> Result<Component, String> {
    use modeldesc::Causality as C;
    Ok(Component {
        name: name.into(),
        source: format!("resources/{fmu}.fmu"),
        inputs: names::<M>(C::Input),
        outputs: names::<M>(C::Output),
        parameters: bindings::<M>(params)?,
    })
}

/// The parameter trees of the four components for the whole-bench tree `p`.
fn component_params(p: &Params) -> [Params; 4] {
    let mut sv2 = p.clone();
    // SV2 is a servovalve.fmu instance; its `sv1.*` parameters carry SV2's values
    sv2.sv1 = *p.sv2_effective();
    let mut act = p.clone();
    // bench.fmu merges the chamber-side half of each N-V passage into the chamber
    // (Circuit::chamber_volume); the manifold FMU leaves it to the actuator, whose only
    // way to hold it is its dead volume (the sides are equal: one passage geometry)
    let extra = Circuit::from_params(p).chamber_volume;
    act.actuator.dead_volume += 0.5 * (extra[0] + extra[1]);
    [p.clone(), sv2, p.clone(), act]
}

/// The bench of `bench.fmu` (thesis parameters, all effects but the payload) in `mode`,
/// as a system of servovalve, manifold and actuator FMUs.
pub fn bench_system(mode: Mode) -> Result<System, String> {
    let p = Params::thesis_bench(mode);
    let [sv1p, sv2p, mp, ap] = component_params(&p);
    // The listing is the Gauss-Seidel order. The actuator goes first: its carried model
    // of the passage must start from the manifold's state at t_n; the manifold, last,
    // starts its carried chamber pressures from the actuator's t_n+1, which costs less
    // accuracy than the converse (docs/cosim.md).
    let components = vec![
        component::<actuator::ActuatorFmu>("actuator", "actuator", &ap)?,
        component::<servovalve::ServovalveFmu>("sv1", "servovalve", &sv1p)?,
        component::<servovalve::ServovalveFmu>("sv2", "servovalve", &sv2p)?,
        component::<manifold::ManifoldFmu>("manifold", "manifold", &mp)?,
    ];
    let end = |e: &str, c: &str| End {
        element: Some(e.into()),
        connector: c.into(),
    };
    let system = |c: &str| End {
        element: None,
        connector: c.into(),
    };
    let mut connections: Vec<Connection> = SYSTEM_INPUTS
        .iter()
        .map(|(s, e, c)| Connection {
            start: system(s),
            end: end(e, c),
        })
        .collect();
    connections.extend(WIRES.iter().map(|(a, b, c, d)| Connection {
        start: end(a, b),
        end: end(c, d),
    }));
    // the chamber port (docs/cosim.md): each side carries the other's element over a
    // step, the manifold the chamber (displaced flow, volume, bulk modulus), the actuator
    // the passage and the node behind it (driving pressure, inertance, volume, feed)
    let chamber_port = actuator::CHAMBER_OUTPUTS
        .iter()
        .map(|v| ("actuator", v.0, "manifold"))
        .chain(
            actuator::PASSAGE_INPUTS
                .iter()
                .map(|v| ("manifold", v.0, "actuator")),
        );
    connections.extend(chamber_port.map(|(a, name, b)| Connection {
        start: end(a, name),
        end: end(b, name),
    }));
    connections.extend(SYSTEM_OUTPUTS.iter().map(|(s, e, c)| Connection {
        start: end(e, c),
        end: system(s),
    }));
    Ok(System {
        name: "HydroBench".into(),
        inputs: SYSTEM_INPUTS.iter().map(|x| x.0.to_string()).collect(),
        outputs: SYSTEM_OUTPUTS.iter().map(|x| x.0.to_string()).collect(),
        components,
        connections,
    })
}

/// Variant SSDs of the closed loop (SSP 1.0 section 3: further SSD files at the package
/// root are variants; a tool without variant support reads SystemStructure.ssd alone).
/// Two, because the wiring differs: mode 1 drives the actuator with SV1 alone and leaves
/// SV2 at null (the controller's u2 is not connected), modes 2 and 3 drive both valves.
pub const CLOSED_LOOP_SSD: &str = "ClosedLoop.ssd";
pub const CLOSED_LOOP_MODE1_SSD: &str = "ClosedLoopMode1.ssd";

/// The variant SSD holding the closed loop in `mode`.
pub fn closed_loop_ssd(mode: Mode) -> &'static str {
    match mode {
        Mode::FourWaySingle => CLOSED_LOOP_MODE1_SSD,
        _ => CLOSED_LOOP_SSD,
    }
}

/// The system of [`bench_system`] closed by a `controller.fmu` instance: system input
/// `y_ref` (and `P_ref`); the controller reads the actuator's y, P1, P2 (the plant's own
/// values: the components have no acquisition delay) and drives the valves. It samples at
/// its own 1 ms period (docs/cosim.md, multi-rate master). Its built-in parameters are the
/// thesis's proportional law (Kp = 1169 V/m): nothing to bind.
pub fn closed_loop_system(mode: Mode) -> Result<System, String> {
    let mut sys = bench_system(mode)?;
    sys.name = match mode {
        Mode::FourWaySingle => "HydroBenchClosedLoopMode1".into(),
        _ => "HydroBenchClosedLoop".into(),
    };
    use modeldesc::Causality as C;
    sys.components.push(Component {
        name: "controller".into(),
        source: "resources/controller.fmu".into(),
        inputs: names::<controller::ControllerFmu>(C::Input),
        outputs: names::<controller::ControllerFmu>(C::Output),
        parameters: vec![],
    });
    // the valve commands come from the controller now, not from outside
    sys.connections.retain(|c| {
        !(c.start.element.is_none() && ["u1", "u2"].contains(&c.start.connector.as_str()))
    });
    sys.inputs.retain(|n| n != "u1" && n != "u2");
    let end = |e: &str, c: &str| End {
        element: Some(e.into()),
        connector: c.into(),
    };
    let mut wires = vec![
        ("actuator", "y", "controller", "y"),
        ("actuator", "P1", "controller", "P1"),
        ("actuator", "P2", "controller", "P2"),
        ("controller", "u1", "sv1", "u"),
    ];
    if mode != Mode::FourWaySingle {
        wires.push(("controller", "u2", "sv2", "u"));
    }
    sys.connections
        .extend(wires.iter().map(|(a, b, c, d)| Connection {
            start: end(a, b),
            end: end(c, d),
        }));
    for input in ["y_ref", "P_ref"] {
        sys.inputs.push(input.into());
        sys.connections.push(Connection {
            start: End {
                element: None,
                connector: input.into(),
            },
            end: end("controller", input),
        });
    }
    Ok(sys)
}

// ---------------------------------------------------------------------------------------
// Writing

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn value_xml(v: &Value) -> String {
    match v {
        // `{:?}` of f64 is the shortest text that reads back to the same number
        Value::Real(x) => format!("<ssv:Real value=\"{x:?}\"/>"),
        Value::Integer(k) => format!("<ssv:Integer value=\"{k}\"/>"),
        Value::Boolean(b) => format!("<ssv:Boolean value=\"{b}\"/>"),
    }
}

/// An ssv:ParameterSet with the given parameters, indented by `pad`.
fn parameter_set(name: &str, params: &[(String, Value)], pad: &str, ns: bool) -> String {
    let xmlns = if ns {
        format!(" xmlns:ssv=\"{NS_SSV}\"")
    } else {
        String::new()
    };
    let mut s = format!(
        "{pad}<ssv:ParameterSet{xmlns} version=\"1.0\" name=\"{}\">\n{pad}  <ssv:Parameters>\n",
        esc(name)
    );
    for (n, v) in params {
        s += &format!(
            "{pad}    <ssv:Parameter name=\"{}\">{}</ssv:Parameter>\n",
            esc(n),
            value_xml(v)
        );
    }
    s + &format!("{pad}  </ssv:Parameters>\n{pad}</ssv:ParameterSet>\n")
}

fn connectors(inputs: &[String], outputs: &[String], pad: &str) -> String {
    let mut s = format!("{pad}<ssd:Connectors>\n");
    for (kind, list) in [("input", inputs), ("output", outputs)] {
        for n in list {
            s += &format!(
                "{pad}  <ssd:Connector name=\"{}\" kind=\"{kind}\"><ssc:Real/></ssd:Connector>\n",
                esc(n)
            );
        }
    }
    s + &format!("{pad}</ssd:Connectors>\n")
}

/// SystemStructure.ssd of a system (SSP 1.0).
pub fn to_ssd(sys: &System, stop_time: f64) -> String {
    let mut s = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <ssd:SystemStructureDescription xmlns:ssd=\"{NS_SSD}\" xmlns:ssc=\"{NS_SSC}\" \
         xmlns:ssv=\"{NS_SSV}\" version=\"1.0\" name=\"{}\" generationTool=\"hbench\">\n",
        esc(&sys.name)
    );
    s += "  <ssd:System name=\"bench\" description=\"Two MOOG D765 servovalves, three-mode \
          manifold and double-rod actuator; pressures absolute, SI units\">\n";
    s += &connectors(&sys.inputs, &sys.outputs, "    ");
    s += "    <ssd:Elements>\n";
    for c in &sys.components {
        s += &format!(
            "      <ssd:Component name=\"{}\" type=\"application/x-fmu-sharedlibrary\" \
             source=\"{}\" implementation=\"CoSimulation\">\n",
            esc(&c.name),
            esc(&c.source)
        );
        s += &connectors(&c.inputs, &c.outputs, "        ");
        if !c.parameters.is_empty() {
            s += "        <ssd:ParameterBindings>\n          <ssd:ParameterBinding>\n\
                  \x20           <ssd:ParameterValues>\n";
            s += &parameter_set(&c.name, &c.parameters, "              ", false);
            s += "            </ssd:ParameterValues>\n          </ssd:ParameterBinding>\n\
                  \x20       </ssd:ParameterBindings>\n";
        }
        s += "      </ssd:Component>\n";
    }
    s += "    </ssd:Elements>\n    <ssd:Connections>\n";
    for c in &sys.connections {
        let attr = |which: &str, e: &End| {
            let el = e
                .element
                .as_ref()
                .map(|x| format!(" {which}Element=\"{}\"", esc(x)))
                .unwrap_or_default();
            format!("{el} {which}Connector=\"{}\"", esc(&e.connector))
        };
        s += &format!(
            "      <ssd:Connection{}{}/>\n",
            attr("start", &c.start),
            attr("end", &c.end)
        );
    }
    s += "    </ssd:Connections>\n  </ssd:System>\n";
    s += &format!("  <ssd:DefaultExperiment startTime=\"0.0\" stopTime=\"{stop_time:?}\"/>\n");
    s + "</ssd:SystemStructureDescription>\n"
}

/// Write `bench.ssp` into `dir`, next to the FMUs it packs (`hbench fmu` calls this after
/// packaging them). The SSD binds mode 3, like `bench.fmu`; resources/mode{1,2,3}.ssv hold
/// the bindings of each mode for tools that swap parameter sets.
pub fn write_package(dir: &Path) -> Result<std::path::PathBuf, String> {
    let sys = bench_system(DEFAULT_MODE)?;
    let path = dir.join("bench.ssp");
    let file = std::fs::File::create(&path)
        .map_err(|e| format!("cannot create {}: {e}", path.display()))?;
    let mut zip = zip::ZipWriter::new(file);
    let opts = SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    let mut add = |name: &str, bytes: &[u8]| -> Result<(), String> {
        zip.start_file(name, opts).map_err(|e| e.to_string())?;
        zip.write_all(bytes).map_err(|e| e.to_string())
    };
    add(SSD, to_ssd(&sys, 0.35).as_bytes())?;
    let variants = [
        closed_loop_system(DEFAULT_MODE)?,
        closed_loop_system(Mode::FourWaySingle)?,
    ];
    for (name, v) in [CLOSED_LOOP_SSD, CLOSED_LOOP_MODE1_SSD]
        .iter()
        .zip(&variants)
    {
        add(name, to_ssd(v, 0.35).as_bytes())?;
    }
    let mut packed = Vec::new();
    for c in variants.iter().flat_map(|v| &v.components) {
        if packed.contains(&c.source) {
            continue;
        }
        let file = Path::new(&c.source)
            .file_name()
            .ok_or("component without a file name")?;
        let fmu = dir.join(file);
        let bytes =
            std::fs::read(&fmu).map_err(|e| format!("cannot read {}: {e}", fmu.display()))?;
        add(&c.source, &bytes)?;
        packed.push(c.source.clone());
    }
    for mode in [Mode::FourWaySingle, Mode::FourWayParallel, Mode::ThreeWay] {
        let sys = bench_system(mode)?;
        let mut text = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
        // one set per file (ssv:ParameterSet is the document element); the parameter
        // names are prefixed with the component, as a system-level binding sees them
        let all: Vec<(String, Value)> = sys
            .components
            .iter()
            .flat_map(|c| {
                c.parameters
                    .iter()
                    .map(move |(n, v)| (format!("{}.{n}", c.name), *v))
            })
            .collect();
        text += &parameter_set(&format!("mode{}", mode.number()), &all, "", true);
        add(
            &format!("resources/mode{}.ssv", mode.number()),
            text.as_bytes(),
        )?;
    }
    zip.finish().map_err(|e| e.to_string())?;
    Ok(path)
}

// ---------------------------------------------------------------------------------------
// Reading

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ssd_round_trips_and_binds_what_the_bench_changes() {
        for mode in [Mode::FourWaySingle, Mode::FourWayParallel, Mode::ThreeWay] {
            let sys = bench_system(mode).unwrap();
            let back = parse_ssd(&to_ssd(&sys, 0.35)).unwrap();
            assert_eq!(back, sys, "{mode:?}");
            let m = sys.component("manifold").unwrap();
            let bound =
                |c: &Component, n: &str| c.parameters.iter().find(|(k, _)| k == n).map(|(_, v)| *v);
            // mode 3 is the manifold's default: bound only when it differs
            let want = (mode != Mode::ThreeWay).then_some(Value::Integer(mode.number() as i32));
            assert_eq!(bound(m, "mode"), want);
            assert_eq!(bound(m, "effect.entrained_air"), Some(Value::Boolean(true)));
            let a = sys.component("actuator").unwrap();
            let Some(Value::Real(v)) = bound(a, "actuator.dead_volume") else {
                panic!("dead volume not bound")
            };
            assert!(v > hbmodel::params::ActuatorParams::default().dead_volume);
            // both ends of every chamber-port term are wired, by the same name
            let wired = |from: &str, name: &str, to: &str| {
                sys.connections.iter().any(|c| {
                    c.start.element.as_deref() == Some(from)
                        && c.end.element.as_deref() == Some(to)
                        && c.start.connector == name
                        && c.end.connector == name
                })
            };
            for (name, _, _) in actuator::CHAMBER_OUTPUTS {
                assert!(wired("actuator", name, "manifold"), "{name}");
            }
            for (name, _, _) in actuator::PASSAGE_INPUTS {
                assert!(wired("manifold", name, "actuator"), "{name}");
            }
            // the closed loop: the controller drives SV2 except in mode 1
            let cl = closed_loop_system(mode).unwrap();
            assert_eq!(parse_ssd(&to_ssd(&cl, 0.35)).unwrap(), cl);
            let drives = |valve: &str| {
                cl.connections.iter().any(|c| {
                    c.start.element.as_deref() == Some("controller")
                        && c.end.element.as_deref() == Some(valve)
                })
            };
            assert!(drives("sv1"));
            assert_eq!(drives("sv2"), mode != Mode::FourWaySingle);
            assert!(!cl.inputs.contains(&"u1".to_string()));
        }
    }
}
