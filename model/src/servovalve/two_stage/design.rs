//! The valve's unprinted constants gathered in one value, and the bench data it needs.

use super::armature::*;
use super::electronics::*;
use super::pilot::*;
use super::spool::*;
use crate::params::{Params, BAR};

/// Every unprinted constant of the model, gathered so that tuning tools can vary them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Design {
    pub rated_stroke: f64,
    pub slot_width: f64,
    pub spool_diameter: f64,
    pub spool_mass: f64,
    pub spool_damping_centre: f64,
    pub spool_damping_slope: f64,
    pub pilot_chamber_volume: f64,
    pub pilot_cd: f64,
    pub inlet_diameter: f64,
    pub nozzle_diameter: f64,
    pub nozzle_gap: f64,
    pub drain_diameter: f64,
    pub armature_inertia: f64,
    pub armature_damping: f64,
    pub tube_stiffness: f64,
    pub tube_length: f64,
    pub flapper_length: f64,
    pub needle_length: f64,
    pub needle_stiffness: f64,
    pub magnet_mmf: f64,
    pub coil_turns: f64,
    pub air_gap: f64,
    pub pole_area: f64,
    pub pole_arm: f64,
    pub coil_resistance: f64,
    pub driver_voltage: f64,
    pub current_loop_gain: f64,
    pub current_limit: f64,
    pub position_gain: f64,
}

impl Default for Design {
    fn default() -> Self {
        Design {
            rated_stroke: RATED_STROKE,
            slot_width: SLOT_WIDTH,
            spool_diameter: SPOOL_DIAMETER,
            spool_mass: SPOOL_MASS,
            spool_damping_centre: SPOOL_DAMPING_CENTRE,
            spool_damping_slope: SPOOL_DAMPING_SLOPE,
            pilot_chamber_volume: PILOT_CHAMBER_VOLUME,
            pilot_cd: PILOT_CD,
            inlet_diameter: INLET_DIAMETER,
            nozzle_diameter: NOZZLE_DIAMETER,
            nozzle_gap: NOZZLE_GAP,
            drain_diameter: DRAIN_DIAMETER,
            armature_inertia: ARMATURE_INERTIA,
            armature_damping: ARMATURE_DAMPING,
            tube_stiffness: TUBE_STIFFNESS,
            tube_length: TUBE_LENGTH,
            flapper_length: FLAPPER_LENGTH,
            needle_length: NEEDLE_LENGTH,
            needle_stiffness: NEEDLE_STIFFNESS,
            magnet_mmf: MAGNET_MMF,
            coil_turns: COIL_TURNS,
            air_gap: AIR_GAP,
            pole_area: POLE_AREA,
            pole_arm: POLE_ARM,
            coil_resistance: COIL_RESISTANCE,
            driver_voltage: DRIVER_VOLTAGE,
            current_loop_gain: CURRENT_LOOP_GAIN,
            current_limit: CURRENT_LIMIT,
            position_gain: POSITION_GAIN,
        }
    }
}

/// Fluid and circuit data the valve needs from the bench.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Environment {
    pub density: f64,
    pub viscosity: f64,
    pub bulk_modulus: f64,
    /// Supply and tank pressure used when the ports are not given (`derivatives`).
    pub supply: f64,
    pub tank: f64,
}

impl Environment {
    /// The oil of a parameter set at its temperature, and its supply and tank.
    pub fn from_params(p: &Params) -> Self {
        let fluid = p.fluid_in_use();
        Environment {
            density: fluid.density,
            viscosity: fluid
                .dynamic_viscosity(fluid.temperature, crate::fluid::ATMOSPHERIC_PRESSURE),
            bulk_modulus: fluid.bulk_modulus,
            supply: p.supply_pressure,
            tank: p.tank_pressure,
        }
    }

    /// The section 2.2.3 experiments: supply 215 bar, tank 2 bar, oil at 40 degC.
    pub fn thesis_test() -> Self {
        Environment::from_params(&Params {
            supply_pressure: 215.0 * BAR,
            tank_pressure: 2.0 * BAR,
            ..Params::default()
        })
    }
}
