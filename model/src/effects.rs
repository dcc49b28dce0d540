//! The effects registry: every physical effect the bench model can switch on and off, by
//! name, with what it needs on to mean anything.
//!
//! A declaration table with no dependency in the crate: the parameter tree
//! ([`crate::params`]) holds the switches as `effects` and declares, in its registry
//! (`params::PARAMS`), which effect owns each parameter.

use serde::{Deserialize, Serialize};

/// What the registry says about one effect.
#[derive(Debug, Clone, Copy)]
pub struct EffectSpec {
    pub effect: Effect,
    pub name: &'static str,
    pub description: &'static str,
    /// Effects that must be on for this one to mean anything.
    pub requires: &'static [Effect],
}

/// Declares every effect from one table: a row `Variant name requires [..]: "description";`
/// gives the `Effect` variant, its `EffectSpec` in `EFFECTS`, its place in `Effect::ALL`
/// and its switch `Effects::name` (serialised under that name), so that adding an effect
/// is adding a row. `name` must be the snake_case of `Variant` (serde's name for the
/// variant); a test below checks it.
macro_rules! effects {
    ($( $variant:ident $name:ident requires [$($needed:ident),*]: $description:literal; )*) => {
        /// A physical effect of the bench model that can be switched on or off.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
        #[serde(rename_all = "snake_case")]
        pub enum Effect {
            $( $variant, )*
        }

        /// Number of effects.
        const COUNT: usize = [$( stringify!($name) ),*].len();

        /// Every effect in declaration order, with what the registry says about it.
        pub const EFFECTS: [EffectSpec; COUNT] = [
            $( EffectSpec {
                effect: Effect::$variant,
                name: stringify!($name),
                description: $description,
                requires: &[$( Effect::$needed ),*],
            }, )*
        ];

        impl Effect {
            pub const ALL: [Effect; COUNT] = [$( Effect::$variant ),*];
        }

        /// On/off switch of every registry effect, serialised under these exact names.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
        #[serde(deny_unknown_fields, default)]
        pub struct Effects {
            $( pub $name: bool, )*
        }

        impl Effects {
            fn slot(&mut self, effect: Effect) -> &mut bool {
                match effect {
                    $( Effect::$variant => &mut self.$name, )*
                }
            }
        }
    };
}

effects! {
    ManifoldVolume manifold_volume requires []:
        "Oil volume of the manifold passages (Table 3.3). Alone: added to each \
            chamber; with manifold_inertia: distributed C-R-I-C passages (3.2)";
    ManifoldInertia manifold_inertia requires []:
        "Inertia of the oil in the manifold passages (3.3). Alone: equivalent \
            mass added to the piston (3.16), Table 3.4; with manifold_volume: \
            distributed C-R-I-C passages";
    ManifoldLosses manifold_losses requires [ManifoldVolume, ManifoldInertia]:
        "Abacus-based pressure drops of the passages (3.5)-(3.7); they act on \
            the passage flows, so they need the distributed passages";
    EntrainedAir entrained_air requires []:
        "Pressure-dependent effective bulk modulus of oil with undissolved air \
            (A.7)-(A.12)";
    InternalLeakage internal_leakage requires []:
        "Laminar leakage paths inside components: across the piston (4.1) and \
            across the servovalve spool lands at null";
    DryFriction dry_friction requires []:
        "Dry and Stribeck friction of the piston, simplified law (4.13) or \
            Sidhom model (4.5)-(4.12)";
    ViscousFriction viscous_friction requires []:
        "Viscous friction of the hydrostatic bearings, b*v (section 4.4)";
    ValveDynamics valve_dynamics requires []:
        "Second-order spool dynamics with a spool-rate limit, tuned to the \
            manufacturer's -3 dB bandwidths (310 Hz at 40 %, 160 Hz at 90 %)";
    ValveAsymmetry valve_asymmetry requires []:
        "SV2 uses its own parameters instead of SV1's (the mode-3 asymmetry the \
            thesis notes in section 4.4)";
    SensorDelay sensor_delay requires []:
        "Delay between the physical signals and the sampled measurements (about \
            0.5 ms on the bench, section 4.4)";
    Payload payload requires []:
        "Payload mass carried by the piston (chapter 7 robustness tests)";
    Temperature temperature requires []:
        "Oil temperature away from the 40 degC reference: viscosity (A.16) scales \
            laminar leakage, laminar passage losses and viscous friction";
}

impl Effect {
    pub fn spec(self) -> &'static EffectSpec {
        // EFFECTS and ALL come from the same table, in its order.
        &EFFECTS[self as usize]
    }

    pub fn name(self) -> &'static str {
        self.spec().name
    }

    pub fn from_name(name: &str) -> Option<Effect> {
        EFFECTS.iter().find(|s| s.name == name).map(|s| s.effect)
    }
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
    fn variants_serialise_under_their_registry_names() {
        // serde names the variant after its own snake_case, the table after `name`
        for spec in EFFECTS {
            let serialised = toml::Value::try_from(spec.effect).unwrap();
            assert_eq!(serialised.as_str(), Some(spec.name));
            let back: Effect = serialised.try_into().unwrap();
            assert_eq!(back, spec.effect);
        }
    }

    #[test]
    fn effect_switches_serialise_under_registry_names() {
        let text = toml::to_string(&Effects::all()).unwrap();
        for spec in EFFECTS {
            assert!(text.contains(&format!("{} = true", spec.name)), "{text}");
        }
    }
}
