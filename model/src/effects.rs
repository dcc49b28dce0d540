//! The effects registry: every physical effect the bench model can switch on and off, by
//! name, with the parameters it owns, their units and their physical bounds.
//!
//! This is the one place where parameters are declared. Parameter defaults are the thesis
//! values held by [`crate::params::Params::default`]; the table below adds what a tool needs
//! to vary them safely (unit, bounds, owning effect). The model-gap workflow, the FMU
//! parameter lists and the TOML validation all read this table.

use serde::{Deserialize, Serialize};

use crate::params::Params;

/// A physical effect of the bench model that can be switched on or off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    ManifoldVolume,
    ManifoldInertia,
    ManifoldLosses,
    EntrainedAir,
    InternalLeakage,
    DryFriction,
    ViscousFriction,
    ValveDynamics,
    ValveAsymmetry,
    SensorDelay,
    Payload,
    Temperature,
}

/// What the registry says about one effect.
#[derive(Debug, Clone, Copy)]
pub struct EffectSpec {
    pub effect: Effect,
    pub name: &'static str,
    pub description: &'static str,
    /// Effects that must be on for this one to mean anything.
    pub requires: &'static [Effect],
}

pub const EFFECTS: [EffectSpec; 12] = [
    EffectSpec {
        effect: Effect::ManifoldVolume,
        name: "manifold_volume",
        description: "Oil volume of the manifold passages (Table 3.3). Alone: added to each \
                      chamber; with manifold_inertia: distributed C-R-I-C passages (3.2)",
        requires: &[],
    },
    EffectSpec {
        effect: Effect::ManifoldInertia,
        name: "manifold_inertia",
        description: "Inertia of the oil in the manifold passages (3.3). Alone: equivalent \
                      mass added to the piston (3.16), Table 3.4; with manifold_volume: \
                      distributed C-R-I-C passages",
        requires: &[],
    },
    EffectSpec {
        effect: Effect::ManifoldLosses,
        name: "manifold_losses",
        description: "Abacus-based pressure drops of the passages (3.5)-(3.7); they act on \
                      the passage flows, so they need the distributed passages",
        requires: &[Effect::ManifoldVolume, Effect::ManifoldInertia],
    },
    EffectSpec {
        effect: Effect::EntrainedAir,
        name: "entrained_air",
        description: "Pressure-dependent effective bulk modulus of oil with undissolved air \
                      (A.7)-(A.12)",
        requires: &[],
    },
    EffectSpec {
        effect: Effect::InternalLeakage,
        name: "internal_leakage",
        description: "Laminar leakage paths inside components: across the piston (4.1) and \
                      across the servovalve spool lands at null",
        requires: &[],
    },
    EffectSpec {
        effect: Effect::DryFriction,
        name: "dry_friction",
        description: "Dry and Stribeck friction of the piston, simplified law (4.13) or \
                      Sidhom model (4.5)-(4.12)",
        requires: &[],
    },
    EffectSpec {
        effect: Effect::ViscousFriction,
        name: "viscous_friction",
        description: "Viscous friction of the hydrostatic bearings, b*v (section 4.4)",
        requires: &[],
    },
    EffectSpec {
        effect: Effect::ValveDynamics,
        name: "valve_dynamics",
        description: "Second-order spool dynamics with a spool-rate limit, tuned to the \
                      manufacturer's -3 dB bandwidths (310 Hz at 40 %, 160 Hz at 90 %)",
        requires: &[],
    },
    EffectSpec {
        effect: Effect::ValveAsymmetry,
        name: "valve_asymmetry",
        description: "SV2 uses its own parameters instead of SV1's (the mode-3 asymmetry the \
                      thesis notes in section 4.4)",
        requires: &[],
    },
    EffectSpec {
        effect: Effect::SensorDelay,
        name: "sensor_delay",
        description: "Delay between the physical signals and the sampled measurements (about \
                      0.5 ms on the bench, section 4.4)",
        requires: &[],
    },
    EffectSpec {
        effect: Effect::Payload,
        name: "payload",
        description: "Payload mass carried by the piston (chapter 7 robustness tests)",
        requires: &[],
    },
    EffectSpec {
        effect: Effect::Temperature,
        name: "temperature",
        description: "Oil temperature away from the 40 degC reference: viscosity (A.16) scales \
                      laminar leakage, laminar passage losses and viscous friction",
        requires: &[],
    },
];

impl Effect {
    pub const ALL: [Effect; 12] = [
        Effect::ManifoldVolume,
        Effect::ManifoldInertia,
        Effect::ManifoldLosses,
        Effect::EntrainedAir,
        Effect::InternalLeakage,
        Effect::DryFriction,
        Effect::ViscousFriction,
        Effect::ValveDynamics,
        Effect::ValveAsymmetry,
        Effect::SensorDelay,
        Effect::Payload,
        Effect::Temperature,
    ];

    pub fn spec(self) -> &'static EffectSpec {
        // EFFECTS is declared in the same order as ALL; the test below keeps them in step.
        &EFFECTS[self as usize]
    }

    pub fn name(self) -> &'static str {
        self.spec().name
    }

    pub fn from_name(name: &str) -> Option<Effect> {
        EFFECTS.iter().find(|s| s.name == name).map(|s| s.effect)
    }

    /// Registry parameters owned by this effect.
    pub fn parameters(self) -> impl Iterator<Item = &'static ParamSpec> {
        PARAMS.iter().filter(move |p| p.effect == Some(self))
    }
}

/// On/off switch of every registry effect, serialised under these exact names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Effects {
    pub manifold_volume: bool,
    pub manifold_inertia: bool,
    pub manifold_losses: bool,
    pub entrained_air: bool,
    pub internal_leakage: bool,
    pub dry_friction: bool,
    pub viscous_friction: bool,
    pub valve_dynamics: bool,
    pub valve_asymmetry: bool,
    pub sensor_delay: bool,
    pub payload: bool,
    pub temperature: bool,
}

impl Effects {
    /// Every effect on: the full bench model of chapter 4.
    pub fn all() -> Self {
        let mut e = Effects::default();
        for effect in Effect::ALL {
            e.set(effect, true);
        }
        e
    }

    fn slot(&mut self, effect: Effect) -> &mut bool {
        match effect {
            Effect::ManifoldVolume => &mut self.manifold_volume,
            Effect::ManifoldInertia => &mut self.manifold_inertia,
            Effect::ManifoldLosses => &mut self.manifold_losses,
            Effect::EntrainedAir => &mut self.entrained_air,
            Effect::InternalLeakage => &mut self.internal_leakage,
            Effect::DryFriction => &mut self.dry_friction,
            Effect::ViscousFriction => &mut self.viscous_friction,
            Effect::ValveDynamics => &mut self.valve_dynamics,
            Effect::ValveAsymmetry => &mut self.valve_asymmetry,
            Effect::SensorDelay => &mut self.sensor_delay,
            Effect::Payload => &mut self.payload,
            Effect::Temperature => &mut self.temperature,
        }
    }

    pub fn get(&self, effect: Effect) -> bool {
        let mut copy = *self;
        *copy.slot(effect)
    }

    pub fn set(&mut self, effect: Effect, on: bool) {
        *self.slot(effect) = on;
    }

    pub fn active(&self) -> impl Iterator<Item = Effect> + '_ {
        Effect::ALL.into_iter().filter(|e| self.get(*e))
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
    fn registry_lists_every_effect_once_in_enum_order() {
        for (i, effect) in Effect::ALL.iter().enumerate() {
            assert_eq!(EFFECTS[i].effect, *effect);
            assert_eq!(Effect::from_name(EFFECTS[i].name), Some(*effect));
        }
        let names = [
            "manifold_volume",
            "manifold_inertia",
            "manifold_losses",
            "entrained_air",
            "internal_leakage",
            "dry_friction",
            "viscous_friction",
            "valve_dynamics",
            "valve_asymmetry",
            "sensor_delay",
            "payload",
            "temperature",
        ];
        let registered: Vec<_> = EFFECTS.iter().map(|s| s.name).collect();
        assert_eq!(registered, names);
    }

    #[test]
    fn effect_switches_serialise_under_registry_names() {
        let text = toml::to_string(&Effects::all()).unwrap();
        for spec in EFFECTS {
            assert!(text.contains(&format!("{} = true", spec.name)), "{text}");
        }
    }

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
