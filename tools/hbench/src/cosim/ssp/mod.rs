//! `bench.ssp`: the bench as systems of component FMUs, written as an SSP 1.0 package
//! (the SSDs, the FMUs under resources/, one parameter set per working mode) and read
//! back by the `hbench cosim` master.
//!
//! - [`systems`]: what the systems hold (components, wiring, parameter bindings);
//! - [`write`]: the SSD text and the package;
//! - [`read`]: the SSD subset HydroBench writes, parsed back.
//!
//! Every system closes inside itself: connections join components only, with no
//! system-level connectors, because DNV's libcosim resolves no other kind; a master
//! addresses a component's variable as `Element.variable` (docs/engines.md).

pub mod read;
pub mod systems;
pub mod write;

pub use read::{open, open_variant, Package};
pub use systems::{closed_loop_ssd, ACTUATOR, CONTROLLER, REFERENCE, SV1, SV2};
pub use write::write_package;

use hbfmu::slave::Value;

/// Name of the system description inside an SSP package (SSP 1.0, section 3).
pub const SSD: &str = "SystemStructure.ssd";

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
