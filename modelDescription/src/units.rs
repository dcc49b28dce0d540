//! The project's unit catalogue (FMI 2.0 `UnitDefinitions`).
//!
//! Variables are exchanged in SI units (the model computes in SI, pressures absolute in Pa);
//! display units only tell a tool how to show a value. FMI 2.0 defines the conversion as
//! `display = factor * value + offset`.

use std::f64::consts::PI;

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

/// Exponents of the SI base units (plus rad) a unit is made of, and the affine map
/// `base = factor * value + offset` from the unit to that SI combination.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct BaseUnit {
    pub kg: i32,
    pub m: i32,
    pub s: i32,
    pub a: i32,
    pub k: i32,
    pub mol: i32,
    pub cd: i32,
    pub rad: i32,
    pub factor: f64,
    pub offset: f64,
}

impl Default for BaseUnit {
    fn default() -> Self {
        BaseUnit {
            kg: 0,
            m: 0,
            s: 0,
            a: 0,
            k: 0,
            mol: 0,
            cd: 0,
            rad: 0,
            factor: 1.0,
            offset: 0.0,
        }
    }
}

impl BaseUnit {
    /// (attribute name, exponent) pairs in schema order.
    pub fn exponents(&self) -> [(&'static str, i32); 8] {
        [
            ("kg", self.kg),
            ("m", self.m),
            ("s", self.s),
            ("A", self.a),
            ("K", self.k),
            ("mol", self.mol),
            ("cd", self.cd),
            ("rad", self.rad),
        ]
    }
}

/// A way to show values of a unit: `display = factor * value + offset`.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct DisplayUnit {
    pub name: String,
    pub factor: f64,
    pub offset: f64,
}

impl DisplayUnit {
    /// The value in this display unit of `value` given in the unit.
    pub fn to_display(&self, value: f64) -> f64 {
        self.factor * value + self.offset
    }

    /// The value in the unit of `display` given in this display unit.
    pub fn from_display(&self, display: f64) -> f64 {
        (display - self.offset) / self.factor
    }
}

/// One `UnitDefinitions/Unit`.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Unit {
    /// Modelica-style unit string, e.g. `m3/(s.Pa)`: the name variables refer to.
    pub name: String,
    pub base_unit: BaseUnit,
    pub display_units: Vec<DisplayUnit>,
}

impl Unit {
    /// The display unit with this name.
    pub fn display_unit(&self, name: &str) -> Option<&DisplayUnit> {
        self.display_units.iter().find(|d| d.name == name)
    }
}

struct Dims {
    kg: i32,
    m: i32,
    s: i32,
    a: i32,
    k: i32,
    rad: i32,
}

const fn dims(kg: i32, m: i32, s: i32) -> Dims {
    Dims {
        kg,
        m,
        s,
        a: 0,
        k: 0,
        rad: 0,
    }
}

fn unit(name: &str, d: Dims, display: &[(&str, f64, f64)]) -> Unit {
    Unit {
        name: name.to_string(),
        base_unit: BaseUnit {
            kg: d.kg,
            m: d.m,
            s: d.s,
            a: d.a,
            k: d.k,
            rad: d.rad,
            ..BaseUnit::default()
        },
        display_units: display
            .iter()
            .map(|&(n, factor, offset)| DisplayUnit {
                name: n.to_string(),
                factor,
                offset,
            })
            .collect(),
    }
}

/// The units HydroBench FMUs may use. All are coherent SI units (base factor 1, offset 0);
/// the display units are the ones hydraulics people read (bar, L/min, mm, degC, ...).
pub fn unit_definitions() -> Vec<Unit> {
    vec![
        unit(
            "Pa",
            dims(1, -1, -2),
            &[("bar", 1e-5, 0.0), ("MPa", 1e-6, 0.0)],
        ),
        unit("m3/s", dims(0, 3, -1), &[("L/min", 60_000.0, 0.0)]),
        unit("m", dims(0, 1, 0), &[("mm", 1e3, 0.0), ("um", 1e6, 0.0)]),
        unit("m/s", dims(0, 1, -1), &[("mm/s", 1e3, 0.0)]),
        unit("m/s2", dims(0, 1, -2), &[]),
        unit("m/s3", dims(0, 1, -3), &[]),
        unit("N", dims(1, 1, -2), &[("kN", 1e-3, 0.0)]),
        unit("N/m", dims(1, 0, -2), &[("N/mm", 1e-3, 0.0)]),
        unit("N.s/m", dims(1, 0, -1), &[]),
        unit(
            "V",
            Dims {
                a: -1,
                ..dims(1, 2, -3)
            },
            &[("mV", 1e3, 0.0)],
        ),
        // Controller gains (e.g. Kp = 1169 V/m in the thesis).
        unit(
            "V/m",
            Dims {
                a: -1,
                ..dims(1, 1, -3)
            },
            &[("V/mm", 1e-3, 0.0)],
        ),
        unit(
            "A",
            Dims {
                a: 1,
                ..dims(0, 0, 0)
            },
            &[("mA", 1e3, 0.0)],
        ),
        unit("kg", dims(1, 0, 0), &[]),
        unit(
            "K",
            Dims {
                k: 1,
                ..dims(0, 0, 0)
            },
            &[("degC", 1.0, -273.15)],
        ),
        unit("s", dims(0, 0, 1), &[("ms", 1e3, 0.0)]),
        unit("1/s", dims(0, 0, -1), &[("Hz", 1.0, 0.0)]),
        // Natural frequencies are computed in rad/s but quoted in Hz in the thesis.
        unit(
            "rad/s",
            Dims {
                rad: 1,
                ..dims(0, 0, -1)
            },
            &[("Hz", 1.0 / (2.0 * PI), 0.0)],
        ),
        // Flow-pressure coefficients of valves and leakage paths.
        unit("m3/(s.Pa)", dims(-1, 4, 1), &[("L/(min.bar)", 6e9, 0.0)]),
        unit("Pa.s", dims(1, -1, -1), &[("mPa.s", 1e3, 0.0)]),
        // Kinematic viscosity, which oil data sheets give in cSt.
        unit("m2/s", dims(0, 2, -1), &[("cSt", 1e6, 0.0)]),
        unit("m3", dims(0, 3, 0), &[("L", 1e3, 0.0), ("cm3", 1e6, 0.0)]),
        unit("m2", dims(0, 2, 0), &[("cm2", 1e4, 0.0), ("mm2", 1e6, 0.0)]),
        unit("kg/m3", dims(1, -3, 0), &[]),
        // Hydraulic inertance of a passage (Pa per m3/s2).
        unit("kg/m4", dims(1, -4, 0), &[]),
    ]
}

/// The unit of [`unit_definitions`] with this name.
pub fn find_unit(name: &str) -> Option<Unit> {
    unit_definitions().into_iter().find(|u| u.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exps(name: &str) -> [i32; 8] {
        find_unit(name)
            .unwrap_or_else(|| panic!("unit {name} missing"))
            .base_unit
            .exponents()
            .map(|(_, e)| e)
    }

    fn mul(a: [i32; 8], b: [i32; 8]) -> [i32; 8] {
        std::array::from_fn(|i| a[i] + b[i])
    }

    fn div(a: [i32; 8], b: [i32; 8]) -> [i32; 8] {
        std::array::from_fn(|i| a[i] - b[i])
    }

    #[test]
    fn required_units_present_and_unique() {
        let all = unit_definitions();
        for name in [
            "Pa",
            "m3/s",
            "m",
            "m/s",
            "m/s2",
            "N",
            "V",
            "kg",
            "K",
            "s",
            "rad/s",
            "m3/(s.Pa)",
            "N.s/m",
            "m3",
            "m2",
            "kg/m3",
            "Pa.s",
        ] {
            assert!(all.iter().any(|u| u.name == name), "{name} missing");
        }
        for (i, u) in all.iter().enumerate() {
            assert!(
                all[i + 1..].iter().all(|w| w.name != u.name),
                "{} twice",
                u.name
            );
            assert_eq!(u.base_unit.factor, 1.0, "{} not coherent SI", u.name);
            assert_eq!(u.base_unit.offset, 0.0, "{} not coherent SI", u.name);
        }
    }

    #[test]
    fn base_unit_exponents_are_dimensionally_consistent() {
        // Each derived unit checked against a product of others, so one wrong exponent
        // shows up as a mismatch rather than agreeing with itself.
        assert_eq!(exps("N"), mul(exps("kg"), exps("m/s2")));
        assert_eq!(exps("Pa"), div(exps("N"), exps("m2")));
        assert_eq!(exps("m3/s"), div(exps("m3"), exps("s")));
        assert_eq!(exps("m3/(s.Pa)"), div(exps("m3/s"), exps("Pa")));
        assert_eq!(exps("N.s/m"), div(exps("N"), exps("m/s")));
        assert_eq!(exps("N/m"), div(exps("N"), exps("m")));
        assert_eq!(exps("Pa.s"), mul(exps("Pa"), exps("s")));
        assert_eq!(exps("m2/s"), div(exps("Pa.s"), exps("kg/m3")));
        assert_eq!(exps("kg/m4"), div(exps("Pa"), div(exps("m3/s"), exps("s"))));
        // Power: V * A = N * m / s.
        assert_eq!(
            mul(exps("V"), exps("A")),
            div(mul(exps("N"), exps("m")), exps("s"))
        );
        assert_eq!(exps("V/m"), div(exps("V"), exps("m")));
        assert_eq!(exps("V"), [1, 2, -3, -1, 0, 0, 0, 0]);
        assert_eq!(exps("K"), [0, 0, 0, 0, 1, 0, 0, 0]);
        assert_eq!(exps("rad/s"), [0, 0, -1, 0, 0, 0, 0, 1]);
    }

    #[test]
    fn every_display_unit_converts_correctly() {
        // (unit, display unit, value in SI, same quantity in the display unit)
        let cases: &[(&str, &str, f64, f64)] = &[
            ("Pa", "bar", 1e5, 1.0),
            ("Pa", "MPa", 21e6, 21.0),
            ("m3/s", "L/min", 1e-3 / 60.0, 1.0),
            ("m", "mm", 0.01, 10.0),
            ("m", "um", 2e-6, 2.0),
            ("m/s", "mm/s", 0.25, 250.0),
            ("N", "kN", 5e3, 5.0),
            ("N/m", "N/mm", 1e3, 1.0),
            ("V", "mV", 0.01, 10.0),
            ("V/m", "V/mm", 1169.0, 1.169),
            ("A", "mA", 0.04, 40.0),
            ("K", "degC", 273.15, 0.0),
            ("K", "degC", 313.15, 40.0),
            ("s", "ms", 0.051, 51.0),
            ("1/s", "Hz", 50.0, 50.0),
            ("rad/s", "Hz", 2.0 * PI * 150.0, 150.0),
            // 1 L/min at 1 bar: 1e-3/60 m3/s over 1e5 Pa.
            ("m3/(s.Pa)", "L/(min.bar)", 1e-3 / 60.0 / 1e5, 1.0),
            ("Pa.s", "mPa.s", 0.03, 30.0),
            ("m2/s", "cSt", 46e-6, 46.0),
            ("m3", "L", 2e-3, 2.0),
            ("m3", "cm3", 1e-6, 1.0),
            ("m2", "cm2", 1e-4, 1.0),
            ("m2", "mm2", 3e-6, 3.0),
        ];
        let mut covered = Vec::new();
        for &(u, d, si, shown) in cases {
            let du = find_unit(u)
                .and_then(|unit| unit.display_unit(d).cloned())
                .unwrap_or_else(|| panic!("{u} has no display unit {d}"));
            let tol = 1e-12 * shown.abs().max(1.0);
            assert!(
                (du.to_display(si) - shown).abs() <= tol,
                "{si} {u} shows as {} {d}, expected {shown}",
                du.to_display(si)
            );
            let back = du.from_display(shown);
            assert!(
                (back - si).abs() <= 1e-12 * si.abs(),
                "{shown} {d} reads back as {back} {u}, expected {si}"
            );
            covered.push((u, d));
        }
        for unit in unit_definitions() {
            for du in &unit.display_units {
                assert!(
                    covered.contains(&(unit.name.as_str(), du.name.as_str())),
                    "display unit {} of {} has no conversion case",
                    du.name,
                    unit.name
                );
            }
        }
    }
}
