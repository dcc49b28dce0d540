//! Physical bounds of the parameters the registry ([`crate::params::PARAMS`]) does not
//! list: the fluid's reference state and viscosity law, the servovalves' ratings and the
//! friction and sensor shape constants. The registry holds what the FMUs expose and the
//! gap workflow fits; these are the rest of the parameter tree, which a parameter file
//! can set all the same. Every real number of the tree is in one of the two tables (a
//! test walks the tree to keep it so), so a file can set nothing unchecked.
//!
//! The thesis prints none of these bounds; each says below how it was chosen. They are
//! wide on purpose: they reject what is not a hydraulic bench (a zero rated pressure drop
//! divides by zero in (II.2)), not what is merely unusual.

use super::Params;

/// One bounded scalar of the parameter tree outside the registry.
pub struct Bound {
    /// Dotted path in the TOML tree.
    pub path: &'static str,
    pub unit: &'static str,
    pub min: f64,
    pub max: f64,
    pub get: fn(&Params) -> f64,
}

macro_rules! bounds {
    ($( $path:literal => |$p:ident| $get:expr, $unit:literal, [$min:expr, $max:expr]; )*) => {
        /// Every real parameter outside the registry, with its physical bounds.
        pub static BOUNDS: &[Bound] = &[
            $( Bound { path: $path, unit: $unit, min: $min, max: $max, get: |$p: &Params| $get }, )*
        ];
    };
}

bounds! {
    // T0 of (A.2): the registry's range of oil temperatures (-10 to 100 degC).
    "fluid.reference_temperature" => |p| p.fluid.reference_temperature, "K", [263.15, 373.15];
    // alpha_P of (A.4): mineral oils 6e-4 to 8e-4 1/K, water glycols ~7e-4; 2e-3 is
    // beyond any hydraulic liquid, 0 is an incompressible-in-temperature idealisation.
    "fluid.expansion_coefficient" => |p| p.fluid.expansion_coefficient, "1/K", [0.0, 2e-3];
    // (A.16): the thesis quotes a1 = 0.6 to 0.75.
    "fluid.walther_a1" => |p| p.fluid.walther_a1, "1", [0.6, 0.75];
    // (A.16) slope and intercept: ASTM D341 lines of oils from ISO VG 2 to VG 1500 have
    // a2 in about -5.5 to -2.5 and a3 in 7 to 14; the bounds take twice that spread, and
    // `viscosity_in_range` below checks the resulting viscosity itself.
    "fluid.walther_a2" => |p| p.fluid.walther_a2, "1", [-8.0, -1.0];
    "fluid.walther_a3" => |p| p.fluid.walther_a3, "1", [3.5, 20.0];
    // C_mu_p of (A.15): mineral oils 1.5e-8 to 3e-8 1/Pa; 0 ignores pressure, 5e-8 is
    // above the stiffest synthetic oils.
    "fluid.barus_coefficient" => |p| p.fluid.barus_coefficient, "1/Pa", [0.0, 5e-8];
    // dPn of (II.2): catalogue servovalves are rated at 35 or 70 bar total drop; 1 bar to
    // 350 bar (the registry's highest supply pressure) keeps the square root defined.
    "sv1.rated_pressure_drop" => |p| p.sv1.rated_pressure_drop, "Pa", [1e5, 350e5];
    "sv2.rated_pressure_drop" => |p| p.sv2.rated_pressure_drop, "Pa", [1e5, 350e5];
    // un of (II.2): the D765 is rated at 10 V; 0.1 V to 100 V spans every voltage-input
    // servovalve while keeping the command ratio defined.
    "sv1.rated_command" => |p| p.sv1.rated_command, "V", [0.1, 100.0];
    "sv2.rated_command" => |p| p.sv2.rated_command, "V", [0.1, 100.0];
    // (4.13) and (4.6)-(4.12): the same scale as the registry's dry-friction bounds
    // (Coulomb to 500 N, Stribeck velocity to 0.1 m/s); velocities up to 1 m/s, the
    // fastest the bench's 19 L/min valves can drive the 9.456 cm2 piston (~0.67 m/s).
    "friction.stribeck_shape" => |p| p.friction.stribeck_shape, "1", [0.0, 5.0];
    "friction.hysteresis" => |p| p.friction.hysteresis, "N", [-500.0, 500.0];
    "friction.linear_velocity" => |p| p.friction.linear_velocity, "m/s", [1e-6, 1.0];
    "friction.sdyn_velocity" => |p| p.friction.sdyn_velocity, "m/s", [1e-6, 1.0];
    "friction.viscous_velocity" => |p| p.friction.viscous_velocity, "m/s", [1e-6, 1.0];
    // |C1+| of (4.10): decay to 1/e over 0.1 mm/s at most.
    "friction.decay_rate" => |p| p.friction.decay_rate, "1/(m/s)", [0.0, 1e4];
    // d+ - b of (4.11): the registry's viscous-friction bound, either sign.
    "friction.mixed_slope" => |p| p.friction.mixed_slope, "N.s/m", [-5000.0, 5000.0];
    // Acquisition: 1 us to 0.1 s periods (the bench samples at 1 kHz); noise up to 1 mm
    // and 10 bar, ten times the worst sensors of the bench's class.
    "sensors.sample_period" => |p| p.sensors.sample_period, "s", [1e-6, 0.1];
    "sensors.position_noise" => |p| p.sensors.position_noise, "m", [0.0, 1e-3];
    "sensors.pressure_noise" => |p| p.sensors.pressure_noise, "Pa", [0.0, 10e5];
    // Sensor spans: within the longest registry stroke (1 m) and the pressure inputs'
    // 0 to 1000 bar.
    "sensors.position_range[0]" => |p| p.sensors.position_range[0], "m", [-1.0, 1.0];
    "sensors.position_range[1]" => |p| p.sensors.position_range[1], "m", [-1.0, 1.0];
    "sensors.pressure_range[0]" => |p| p.sensors.pressure_range[0], "Pa", [0.0, 1e8];
    "sensors.pressure_range[1]" => |p| p.sensors.pressure_range[1], "Pa", [0.0, 1e8];
}

/// Kinematic viscosities (cSt) the Walther line (A.16) may give at the oil and reference
/// temperatures: ISO VG 2 at its hottest (about 1 cSt) to VG 1500 cold (about 1e5 cSt).
pub const VISCOSITY_RANGE_CST: (f64, f64) = (0.5, 1e5);

/// The Walther line's viscosity at `t` lies in [`VISCOSITY_RANGE_CST`]: bounded a2, a3
/// alone still allow 10^(10^20).
pub fn viscosity_in_range(p: &Params, t: f64) -> Result<(), String> {
    let nu_cst = p.fluid.kinematic_viscosity(t) * 1e6;
    let (lo, hi) = VISCOSITY_RANGE_CST;
    if nu_cst.is_finite() && (lo..=hi).contains(&nu_cst) {
        Ok(())
    } else {
        Err(format!(
            "the Walther constants give a viscosity of {nu_cst} cSt at {t} K, outside [{lo}, {hi}] cSt"
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::PARAMS;

    /// Every real number in the TOML form of the tree, by dotted path (arrays indexed).
    fn numeric_leaves(v: &toml::Value, prefix: &str, out: &mut Vec<String>) {
        match v {
            toml::Value::Table(t) => {
                for (k, x) in t {
                    let path = if prefix.is_empty() {
                        k.clone()
                    } else {
                        format!("{prefix}.{k}")
                    };
                    numeric_leaves(x, &path, out);
                }
            }
            toml::Value::Array(a) => {
                for (i, x) in a.iter().enumerate() {
                    numeric_leaves(x, &format!("{prefix}[{i}]"), out);
                }
            }
            toml::Value::Float(_) => out.push(prefix.to_string()),
            _ => {}
        }
    }

    #[test]
    fn every_real_of_the_tree_is_bounded_once() {
        let tree: toml::Value = toml::from_str(&Params::default().to_toml()).unwrap();
        let mut leaves = vec![];
        numeric_leaves(&tree, "", &mut leaves);
        assert!(leaves.len() > 40, "{leaves:?}");
        for leaf in &leaves {
            let n = PARAMS.iter().filter(|s| s.path == leaf).count()
                + BOUNDS.iter().filter(|b| b.path == leaf).count();
            assert_eq!(n, 1, "{leaf} is bounded {n} times");
        }
    }

    #[test]
    fn defaults_lie_within_bounds() {
        let p = Params::default();
        for b in BOUNDS {
            let v = (b.get)(&p);
            assert!(v >= b.min && v <= b.max, "{} = {v}", b.path);
        }
        viscosity_in_range(&p, p.fluid.temperature).unwrap();
    }
}
