//! Writing `bench.ssp`: the SSD text of a [`System`] and the package around it.

use std::io::Write;
use std::path::Path;

use hbfmu::slave::Value;
use hbmodel::Mode;
use zip::write::SimpleFileOptions;

#[cfg(doc)]
use super::systems::move_reference;
use super::systems::{bench_system, closed_loop_ssd, closed_loop_system, DEFAULT_MODE, MOVE_STOP};
use super::{End, System, SSD};

const NS_SSD: &str = "http://ssp-standard.org/SSP1/SystemStructureDescription";
const NS_SSC: &str = "http://ssp-standard.org/SSP1/SystemStructureCommon";
const NS_SSV: &str = "http://ssp-standard.org/SSP1/SystemStructureParameterValues";
/// OMSimulator's namespace for its annotations.
const NS_OMS: &str =
    "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd";

/// Communication step an engine without its own choice uses (s): 0.1 ms, where the
/// system of components stays within the bounds docs/cosim.md gives against bench.fmu.
pub const COMMUNICATION_STEP: f64 = 1e-4;

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
    if inputs.is_empty() && outputs.is_empty() {
        return String::new();
    }
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
         xmlns:ssv=\"{NS_SSV}\" xmlns:oms=\"{NS_OMS}\" version=\"1.0\" name=\"{}\" generationTool=\"hbench\">\n",
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
    s += "    </ssd:Connections>\n";
    // OMSimulator imports a system only with its own master settings (an SSP tool
    // annotation); other engines skip an annotation type they do not know
    s += &format!(
        "    <ssd:Annotations>\n      <ssc:Annotation type=\"org.openmodelica\">\n\
         \x20       <oms:Annotations>\n          <oms:SimulationInformation>\n\
         \x20           <oms:FixedStepMaster description=\"oms-ma\" stepSize=\"{COMMUNICATION_STEP:?}\"/>\n\
         \x20         </oms:SimulationInformation>\n        </oms:Annotations>\n\
         \x20     </ssc:Annotation>\n    </ssd:Annotations>\n  </ssd:System>\n"
    );
    // without its own (here empty) simulation settings OMSimulator warns of "deprecated
    // content"; its defaults and command line then apply
    s += &format!(
        "  <ssd:DefaultExperiment startTime=\"0.0\" stopTime=\"{stop_time:?}\">\n\
         \x20   <ssd:Annotations>\n      <ssc:Annotation type=\"org.openmodelica\">\n\
         \x20       <oms:Annotations><oms:SimulationInformation/></oms:Annotations>\n\
         \x20     </ssc:Annotation>\n    </ssd:Annotations>\n  </ssd:DefaultExperiment>\n"
    );
    s + "</ssd:SystemStructureDescription>\n"
}

/// Write `bench.ssp` into `dir`, next to the FMUs it packs (`hbench fmu` calls this after
/// packaging them). SystemStructure.ssd is the open bench in mode 3, like `bench.fmu`;
/// ClosedLoop*.ssd run the move of [`move_reference`] in each mode; resources/mode{1,2,3}.ssv
/// hold the open bench's bindings of each mode for tools that swap parameter sets.
///
/// No OspSystemStructure.xml: libcosim reads the SSDs themselves, and one description
/// read by every engine cannot drift from a second one read by one engine.
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
    add(SSD, to_ssd(&sys, MOVE_STOP).as_bytes())?;
    let mut variants = vec![];
    for mode in [Mode::FourWaySingle, Mode::FourWayParallel, Mode::ThreeWay] {
        let v = closed_loop_system(mode)?;
        add(closed_loop_ssd(mode), to_ssd(&v, MOVE_STOP).as_bytes())?;
        variants.push(v);
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
