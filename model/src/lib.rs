//! HydroBench bench physics: fluid, servovalves, manifold, actuator, the assembled
//! bench and its stiff integration. Pure Rust, no FFI; every FMU and tool stands on it.
//!
//! Units are SI everywhere (Pa absolute, m, m3/s, s, N, V, kg, K). Display units only
//! appear in the FMU model descriptions and in command-line output.

pub mod actuator;
pub mod bench;
pub mod component;
pub mod control;
pub mod effects;
pub mod fluid;
pub mod friction;
pub mod jacobian;
pub mod manifold;
pub mod params;
pub mod sensors;
pub mod servovalve;
pub mod solver;

pub use bench::{Bench, Inputs, Outputs, SimState, Simulation};
pub use effects::{Effect, Effects};
pub use params::{Mode, Params};
