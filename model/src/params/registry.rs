//! The parameter registry: every scalar parameter the tools may vary (the FMUs publish
//! them, the gap workflow fits within their bounds), by dotted path in the tree, with its
//! unit, physical bounds and owning effect.
//!
//! Parameter defaults are the thesis values held by [`Params::default`]; this table adds
//! what a tool needs to vary them safely. The TOML validation, the FMU parameter lists
//! and the model-gap workflow all read it.

use super::Params;
use crate::effects::Effect;

impl Effect {
    /// Registry parameters owned by this effect.
    pub fn parameters(self) -> impl Iterator<Item = &'static ParamSpec> {
        PARAMS.iter().filter(move |p| p.effect == Some(self))
    }
}

/// A scalar model parameter: its path in the parameter tree, unit, bounds and owner.
#[derive(Debug, Clone, Copy)]
pub struct ParamSpec {
    /// Dotted path in the TOML parameter tree, e.g. `actuator.internal_leakage`.
    pub path: &'static str,
    pub unit: &'static str,
    /// Physical lower and upper bounds (inclusive).
    pub min: f64,
    pub max: f64,
    /// The effect that owns the parameter, if it belongs to one.
    pub effect: Option<Effect>,
    pub description: &'static str,
    get: fn(&Params) -> f64,
    set: fn(&mut Params, f64),
}

impl ParamSpec {
    pub fn get(&self, p: &Params) -> f64 {
        (self.get)(p)
    }
    pub fn set(&self, p: &mut Params, value: f64) {
        (self.set)(p, value)
    }
    /// The built-in (thesis) value.
    pub fn default_value(&self) -> f64 {
        self.get(&Params::default())
    }
}

/// Look a parameter up by its dotted path.
pub fn param(path: &str) -> Option<&'static ParamSpec> {
    PARAMS.iter().find(|p| p.path == path)
}

macro_rules! params {
    ($( $path:literal => $($field:ident).+ , $unit:literal, [$min:expr, $max:expr], $effect:expr, $desc:literal; )*) => {
        /// Every scalar parameter of the bench model.
        pub static PARAMS: &[ParamSpec] = &[
            $( ParamSpec {
                path: $path,
                unit: $unit,
                min: $min,
                max: $max,
                effect: $effect,
                description: $desc,
                get: |p: &Params| p.$($field).+,
                set: |p: &mut Params, v: f64| p.$($field).+ = v,
            }, )*
        ];
    };
}

use Effect as E;

params! {
    "supply_pressure" => supply_pressure, "Pa", [10e5, 350e5], None,
        "Supply pressure at the servovalve P ports (absolute)";
    "tank_pressure" => tank_pressure, "Pa", [0.2e5, 20e5], None,
        "Tank pressure at the servovalve T ports and flow reducers (absolute)";
    "initial_position" => initial_position, "m", [-0.15, 0.15], None,
        "Piston position at t = 0 (0 = mid stroke, positive extends chamber 1)";
    "fluid.density" => fluid.density, "kg/m3", [780.0, 950.0], None,
        "Oil density at the reference pressure and temperature";
    "fluid.bulk_modulus" => fluid.bulk_modulus, "Pa", [0.5e9, 2.5e9], None,
        "Bulk modulus of the liquid (1.7e9 reproduces Table 3.5)";
    "fluid.air_fraction" => fluid.air_fraction, "1", [0.0, 0.1], Some(E::EntrainedAir),
        "Volume fraction of undissolved air at atmospheric pressure (A.7)";
    "fluid.temperature" => fluid.temperature, "K", [263.15, 373.15], Some(E::Temperature),
        "Oil temperature";
    "actuator.area" => actuator.area, "m2", [1e-5, 1e-2], None,
        "Active piston area A";
    "actuator.stroke" => actuator.stroke, "m", [0.05, 1.0], None,
        "Usable stroke; chamber volumes are V_dead + A*(stroke/2 +- y)";
    "actuator.dead_volume" => actuator.dead_volume, "m3", [1e-7, 1e-3], None,
        "Dead volume at each end of the actuator";
    "actuator.mass" => actuator.mass, "kg", [0.1, 500.0], None,
        "Moving mass (rod and piston)";
    "actuator.payload_mass" => actuator.payload_mass, "kg", [0.0, 200.0], Some(E::Payload),
        "Payload carried by the piston";
    "actuator.internal_leakage" => actuator.internal_leakage, "m3/(s.Pa)", [0.0, 1e-11], Some(E::InternalLeakage),
        "Laminar leakage coefficient across the piston, Q12 = K (P1 - P2), at the reference temperature";
    "actuator.external_leakage" => actuator.external_leakage, "m3/(s.Pa)", [0.0, 1e-11], Some(E::InternalLeakage),
        "Laminar leakage coefficient of each chamber to the drain (negligible with hydrostatic bearings)";
    "actuator.viscous_friction" => actuator.viscous_friction, "N.s/m", [0.0, 5000.0], Some(E::ViscousFriction),
        "Viscous friction coefficient b at the reference temperature";
    "friction.coulomb" => friction.coulomb, "N", [0.0, 500.0], Some(E::DryFriction),
        "Coulomb friction F_C (4.13)";
    "friction.static_peak" => friction.static_peak, "N", [0.0, 1000.0], Some(E::DryFriction),
        "Dry dynamic friction peak F_sdyn (4.13)";
    "friction.stribeck_velocity" => friction.stribeck_velocity, "m/s", [1e-5, 0.1], Some(E::DryFriction),
        "Stribeck velocity v0 (4.13)";
    "manifold.volume_scale" => manifold.volume_scale, "1", [0.3, 3.0], Some(E::ManifoldVolume),
        "Multiplier of every passage volume (1 = Table 3.3)";
    "manifold.inertia_scale" => manifold.inertia_scale, "1", [0.3, 3.0], Some(E::ManifoldInertia),
        "Multiplier of every passage inertance (1 = Table 3.4)";
    "manifold.loss_scale" => manifold.loss_scale, "1", [0.0, 10.0], Some(E::ManifoldLosses),
        "Multiplier of every passage pressure drop (1 = abacus-based method, Table 3.2)";
    "sv1.rated_flow" => sv1.rated_flow, "m3/s", [1e-5, 2e-3], None,
        "SV1 rated flow at rated command and rated total pressure drop";
    "sv1.null_bias" => sv1.null_bias, "V", [-1.0, 1.0], None,
        "SV1 command offset of the hydraulic null";
    "sv1.null_leakage" => sv1.null_leakage, "m3/(s.Pa)", [0.0, 1e-11], Some(E::InternalLeakage),
        "SV1 total spool-land leakage at null per unit supply-to-tank pressure";
    "sv1.null_width" => sv1.null_width, "1", [0.001, 0.2], Some(E::InternalLeakage),
        "SV1 spool travel (fraction of rated) over which the null leakage passes from one land to the other; sets the pressure gain";
    "sv1.natural_frequency" => sv1.natural_frequency, "rad/s", [200.0, 20000.0], Some(E::ValveDynamics),
        "SV1 spool natural frequency (second-order model)";
    "sv1.damping" => sv1.damping, "1", [0.1, 3.0], Some(E::ValveDynamics),
        "SV1 spool damping ratio";
    "sv1.max_spool_rate" => sv1.max_spool_rate, "1/s", [50.0, 5000.0], Some(E::ValveDynamics),
        "SV1 spool rate limit, in rated strokes per second (pilot-stage flow saturation)";
    "sv2.rated_flow" => sv2.rated_flow, "m3/s", [1e-5, 2e-3], Some(E::ValveAsymmetry),
        "SV2 rated flow (used when valve_asymmetry is on)";
    "sv2.null_bias" => sv2.null_bias, "V", [-1.0, 1.0], Some(E::ValveAsymmetry),
        "SV2 command offset of the hydraulic null (used when valve_asymmetry is on)";
    "sv2.null_leakage" => sv2.null_leakage, "m3/(s.Pa)", [0.0, 1e-11], None,
        "SV2 null leakage (used when valve_asymmetry is on)";
    "sv2.null_width" => sv2.null_width, "1", [0.001, 0.2], None,
        "SV2 null width (used when valve_asymmetry is on)";
    "sv2.natural_frequency" => sv2.natural_frequency, "rad/s", [200.0, 20000.0], None,
        "SV2 spool natural frequency (used when valve_asymmetry is on)";
    "sv2.damping" => sv2.damping, "1", [0.1, 3.0], None,
        "SV2 spool damping ratio (used when valve_asymmetry is on)";
    "sv2.max_spool_rate" => sv2.max_spool_rate, "1/s", [50.0, 5000.0], None,
        "SV2 spool rate limit (used when valve_asymmetry is on)";
    "sensors.delay" => sensors.delay, "s", [0.0, 5e-3], Some(E::SensorDelay),
        "Delay between physical signals and their samples";
    "solver.rtol" => solver.rtol, "1", [1e-12, 1e-2], None,
        "Relative tolerance of the stiff integrator";
    // last: the FMUs append it after their other variables (stable value references)
    "solver.fixed_step" => solver.fixed_step, "s", [0.0, 1e-2], None,
        "Step of the fixed-step real-time mode (L-stable SDIRK2, bounded Newton); 0 keeps the adaptive solver";
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_lie_within_bounds_and_paths_are_unique() {
        let mut seen = std::collections::HashSet::new();
        for p in PARAMS {
            assert!(seen.insert(p.path), "duplicate {}", p.path);
            let v = p.default_value();
            assert!(
                v >= p.min && v <= p.max,
                "{} = {v} outside [{}, {}]",
                p.path,
                p.min,
                p.max
            );
        }
    }

    #[test]
    fn every_effect_but_switch_only_ones_owns_parameters() {
        // manifold_inertia etc. own scales; the pure switches are documented here.
        for effect in Effect::ALL {
            let n = effect.parameters().count();
            assert!(n > 0, "{} owns no parameter", effect.name());
        }
    }

    #[test]
    fn set_then_get_by_path_round_trips() {
        let mut p = Params::default();
        let spec = param("actuator.viscous_friction").unwrap();
        spec.set(&mut p, 123.0);
        assert_eq!(p.actuator.viscous_friction, 123.0);
        assert_eq!(spec.get(&p), 123.0);
    }
}
