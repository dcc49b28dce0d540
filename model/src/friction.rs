//! Piston/barrel friction of the Haenchen hydrostatic-bearing actuator, thesis section 4.2
//! (Y. Xu, INSA Lyon 2013, text lines 5228-5440): the Sidhom model (4.5)-(4.12) and the
//! simplified control-design law (4.13). The viscous term b*v is kept separate
//! ([`viscous_friction`]) because chapter 4 adds it to (4.13) as its own term
//! (assumption 3, line 5481) with b = 400 N/(m/s) (line 5716).
//!
//! # Reconstruction of the garbled equations
//!
//! The PDF extraction scrambles the typography; this is how the printed pieces were read.
//!
//! * (4.13), lines 5426-5435: the fragments `-C`, `|v|`, `v0` above `e` and `tanh(v/v0)`
//!   read as `F_fs(v) = (F_C + (F_sdyn - F_C) exp(-C |v| / v0)) tanh(v / v0)`, the Tustin
//!   exponential Stribeck curve the text names (line 5329) made continuous by the tanh.
//!   Cross-check: its slope at v = 0 is `F_sdyn / v0`, exactly the dry part of the friction
//!   gain `K_fr = (b + F_sdyn / v0) / M` of the linearised model (4.17)-(4.19).
//! * (4.9)/(4.5): `K v` on `[0, v0+[`. A hydrostatic bearing has no adhesion (line 5333),
//!   so a steep linear zone through the origin replaces it; `K = F_sdyn / v0` is the only
//!   slope that meets (4.10), which starts at `F_sdyn` when `v = v0`.
//! * (4.10)/(4.6): `F_Ci + (F_sdyn - F_Ci) exp(C1 (v - v0))` with i = 1 for a > 0 and
//!   i = 2 for a < 0. The exponential must decay from the Stribeck peak, so the printed
//!   `C1` is negative; [`FrictionParams::decay_rate`] stores its magnitude.
//! * (4.11)/(4.7): `F_C2 + d (v - v_sdyn)` on `[v_sdyn, v_max]`. It starts at `F_C2` for
//!   *both* branches, so the hysteresis loop of (4.10) closes at `v_sdyn`, as it should:
//!   Fig. 4.3 draws no hysteresis in the hydrodynamic regime. The printed exponential only
//!   tends to `F_Ci` asymptotically, so we add to (4.10) the straight line that is zero at
//!   `v0` and cancels the residual gap to `F_C2` at `v_sdyn`; the loop is then closed and
//!   every region join is exact.
//! * (4.12)/(4.8): `b (v - v_max)` beyond the experimental low-speed band, which can only
//!   be the viscous regime (printed as-is it would jump to zero at `v_max`). Because the
//!   caller adds `b v` in every region, the dry part is frozen there at its `v_max` value,
//!   and the slope `d` of (4.11) is stored as its excess over `b`
//!   ([`FrictionParams::mixed_slope`]).
//! * Negative velocities mirror the positive ones (F(-v) = -F(v)): the thesis prints
//!   separate +/- constants but no values, so one symmetric set is used.
//!
//! # Default values
//!
//! The thesis prints no dry-friction numbers. The defaults are anchored on what it does
//! print: the damping ratio xi_v = 0.04 of the linearised actuator with omega_n = 1833 rad/s
//! and M = 5.8 kg (line 5651) gives `K_fr = 2 xi_v omega_n = 146.6 1/s`, i.e.
//! `b + F_sdyn / v0 = 850 N/(m/s)`; with b = 400 this leaves `F_sdyn / v0 = 450 N/(m/s)`.
//! The low-speed band where friction is hard to identify is +-0.07 m/s (line 5411).

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// N/(m/s), viscous coefficient b of the AMESim whole-bench model (section 4.4, line 5716).
pub const THESIS_VISCOUS_COEFFICIENT: f64 = 400.0;

/// N, F_C: the stall force A * P_P of the bench is 9.456e-4 m2 * 210e5 Pa = 19.9 kN, and a
/// hydrostatic bearing has friction of order 0.05-0.1 % of it; half of the breakaway level
/// below is a usual Coulomb/Stribeck ratio for lubricated contacts.
pub const DEFAULT_COULOMB: f64 = 10.0;

/// N, F_sdyn: 0.1 % of the 19.9 kN stall force (about 0.2 bar of chamber pressure
/// difference), the "tens of newtons" of a low-friction hydrostatic bearing.
pub const DEFAULT_STATIC_PEAK: f64 = 20.0;

/// m/s, v0 of (4.13): gives `F_sdyn / v0 = 444 N/(m/s)`, so that (4.19) reproduces the
/// printed damping ratio 0.04 (see the module notes).
pub const DEFAULT_STRIBECK_VELOCITY: f64 = 0.045;

/// C of (4.13). 0.5 puts the Stribeck hump at 1.6 v0 = 0.073 m/s, the edge of the +-0.07 m/s
/// band, and keeps the most negative slope of (4.13) near -25 N/(m/s), far below b: the total
/// friction stays monotonic, i.e. no stick-slip, as expected of a hydrostatic bearing.
pub const DEFAULT_STRIBECK_SHAPE: f64 = 0.5;

/// N, F_C1 - F_C2 of (4.6)/(4.10): friction lag loops of lubricated contacts are a fraction
/// of the Stribeck drop F_sdyn - F_C; 40 % of it.
pub const DEFAULT_HYSTERESIS: f64 = 4.0;

/// m/s, v0+ of (4.9): the linear zone replacing adhesion is short compared with the
/// +-0.07 m/s band; 0.01 m/s leaves four fifths of the band to the Stribeck decay
/// (slope F_sdyn / v0+ = 2000 N/(m/s), a stiff but smooth substitute for sticking).
pub const DEFAULT_LINEAR_VELOCITY: f64 = 0.01;

/// m/s, v_sdyn+ of (4.10)/(4.11): end of the Stribeck decay, inside the +-0.07 m/s band
/// with 0.02 m/s left for the mixed regime (4.11).
pub const DEFAULT_SDYN_VELOCITY: f64 = 0.05;

/// m/s, v_max~ of (4.11)/(4.12): the thesis gives the low-speed band as "nearly +-0.07 m/s".
pub const DEFAULT_VISCOUS_VELOCITY: f64 = 0.07;

/// 1/(m/s), |C1+| of (4.10): three decay lengths over [v0+, v_sdyn+] (e^-3 = 5 % residual),
/// so the closing line added to (4.10) is a small correction.
pub const DEFAULT_DECAY_RATE: f64 = 75.0;

/// N/(m/s), d - b of (4.11): the thesis says slopes fitted inside the +-0.07 m/s band are
/// unreliable (line 5411), so by default the mixed regime has no slope beyond the viscous b.
pub const DEFAULT_MIXED_SLOPE: f64 = 0.0;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrictionLaw {
    /// (4.13): symmetric, no hysteresis; the law used for control design in the thesis.
    Simplified,
    /// (4.5)-(4.12): piecewise Sidhom model with acceleration-dependent branches.
    Sidhom,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FrictionParams {
    pub law: FrictionLaw,
    /// N, F_C of (4.13); also F_C2 of (4.10)-(4.11), so that both laws share the same dry
    /// level at high speed.
    pub coulomb: f64,
    /// N, F_sdyn of (4.10)/(4.13): the Stribeck peak (reached by (4.10) at v0+; (4.13) tends to
    /// it only as the bracket value at v = 0, its actual hump is lower).
    pub static_peak: f64,
    /// m/s, v0 of (4.13).
    pub stribeck_velocity: f64,
    /// C of (4.13), dimensionless.
    pub stribeck_shape: f64,
    /// N, F_C1 - F_C2 of (4.6)/(4.10), Sidhom only: asymptote of the accelerating branch
    /// above the decelerating one.
    pub hysteresis: f64,
    /// m/s, v0+ of (4.9)/(4.10), end of the linear zone, Sidhom only.
    pub linear_velocity: f64,
    /// m/s, v_sdyn+ of (4.10)/(4.11), end of the Stribeck decay, Sidhom only.
    pub sdyn_velocity: f64,
    /// m/s, v_max~ of (4.11)/(4.12), onset of the purely viscous regime, Sidhom only.
    pub viscous_velocity: f64,
    /// 1/(m/s), |C1+| of (4.10), Sidhom only.
    pub decay_rate: f64,
    /// N/(m/s), d+ - b of (4.11): slope of the dry part in the mixed regime, Sidhom only.
    pub mixed_slope: f64,
}

impl Default for FrictionParams {
    fn default() -> Self {
        Self {
            law: FrictionLaw::Simplified,
            coulomb: DEFAULT_COULOMB,
            static_peak: DEFAULT_STATIC_PEAK,
            stribeck_velocity: DEFAULT_STRIBECK_VELOCITY,
            stribeck_shape: DEFAULT_STRIBECK_SHAPE,
            hysteresis: DEFAULT_HYSTERESIS,
            linear_velocity: DEFAULT_LINEAR_VELOCITY,
            sdyn_velocity: DEFAULT_SDYN_VELOCITY,
            viscous_velocity: DEFAULT_VISCOUS_VELOCITY,
            decay_rate: DEFAULT_DECAY_RATE,
            mixed_slope: DEFAULT_MIXED_SLOPE,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Error)]
pub enum FrictionError {
    #[error("friction parameter `{name}` = {value} {requirement}")]
    Invalid {
        name: &'static str,
        value: f64,
        requirement: &'static str,
    },
}

impl FrictionParams {
    /// Checks the conditions under which [`dry_friction`] is finite and continuous.
    pub fn validate(&self) -> Result<(), FrictionError> {
        let check = |name, value: f64, ok: bool, requirement| {
            if ok && value.is_finite() {
                Ok(())
            } else {
                Err(FrictionError::Invalid {
                    name,
                    value,
                    requirement,
                })
            }
        };
        check("coulomb", self.coulomb, self.coulomb >= 0.0, "must be >= 0")?;
        check(
            "static_peak",
            self.static_peak,
            self.static_peak >= 0.0,
            "must be >= 0",
        )?;
        check(
            "stribeck_velocity",
            self.stribeck_velocity,
            self.stribeck_velocity > 0.0,
            "must be > 0",
        )?;
        check(
            "stribeck_shape",
            self.stribeck_shape,
            self.stribeck_shape >= 0.0,
            "must be >= 0",
        )?;
        check("hysteresis", self.hysteresis, true, "must be finite")?;
        check(
            "linear_velocity",
            self.linear_velocity,
            self.linear_velocity > 0.0,
            "must be > 0",
        )?;
        check(
            "sdyn_velocity",
            self.sdyn_velocity,
            self.sdyn_velocity > self.linear_velocity,
            "must exceed linear_velocity",
        )?;
        check(
            "viscous_velocity",
            self.viscous_velocity,
            self.viscous_velocity >= self.sdyn_velocity,
            "must be >= sdyn_velocity",
        )?;
        check(
            "decay_rate",
            self.decay_rate,
            self.decay_rate > 0.0,
            "must be > 0",
        )?;
        check("mixed_slope", self.mixed_slope, true, "must be finite")
    }
}

/// Dry friction force (N), opposing motion: positive for v>0. `accelerating` selects the (4.6)/(4.10)
/// branch (a>0 in the direction of motion) for the Sidhom law; ignored by the simplified law.
///
/// Continuous in `v`, zero at `v = 0`, odd in `v`, and bounded for any `v` (parameters
/// satisfying [`FrictionParams::validate`]).
pub fn dry_friction(p: &FrictionParams, v: f64, accelerating: bool) -> f64 {
    match p.law {
        FrictionLaw::Simplified => simplified(p, v),
        // The +/- halves (4.5)-(4.8) and (4.9)-(4.12) are mirror images with one parameter
        // set; "accelerating" means speeding up, so the branch is the same on both sides.
        FrictionLaw::Sidhom => v.signum() * sidhom_positive(p, v.abs(), accelerating),
    }
}

/// d/dv of [`dry_friction`] (N/(m/s)) on the branch `accelerating` selects, the
/// derivative of the region the velocity lies in (the right one at a region boundary).
pub fn dry_friction_slope(p: &FrictionParams, v: f64, accelerating: bool) -> f64 {
    match p.law {
        FrictionLaw::Simplified => {
            // (4.13) F = (F_C + (F_sdyn - F_C) e^(-C|x|)) tanh(x), x = v/v0
            let x = v / p.stribeck_velocity;
            let decay = (-p.stribeck_shape * x.abs()).exp();
            let level = p.coulomb + (p.static_peak - p.coulomb) * decay;
            let d_level = -(p.static_peak - p.coulomb) * p.stribeck_shape * x.signum() * decay;
            let t = x.tanh();
            (d_level * t + level * (1.0 - t * t)) / p.stribeck_velocity
        }
        // F(v) = sign(v) F+(|v|): F'(v) = F+'(|v|)
        FrictionLaw::Sidhom => sidhom_positive_slope(p, v.abs(), accelerating),
    }
}

/// d/ds of [`sidhom_positive`].
fn sidhom_positive_slope(p: &FrictionParams, s: f64, accelerating: bool) -> f64 {
    if s < p.linear_velocity {
        p.static_peak / p.linear_velocity
    } else if s < p.sdyn_velocity {
        stribeck_decay(p, s, accelerating).1
    } else if s < p.viscous_velocity {
        p.mixed_slope
    } else {
        0.0
    }
}

/// The Stribeck decay (4.10) on [v0+, v_sdyn+] and its slope, at speed `s`.
fn stribeck_decay(p: &FrictionParams, s: f64, accelerating: bool) -> (f64, f64) {
    let f_c2 = p.coulomb;
    let f_ci = if accelerating {
        f_c2 + p.hysteresis
    } else {
        f_c2
    };
    // (4.10); the printed C1+ is negative, hence the minus sign on the stored magnitude.
    let decay = |v: f64| (-p.decay_rate * (v - p.linear_velocity)).exp();
    let printed = |v: f64| f_ci + (p.static_peak - f_ci) * decay(v);
    // Closes the loop onto (4.11)'s F_C2 at v_sdyn+ without moving the (4.9) join.
    let gap_at_end = printed(p.sdyn_velocity) - f_c2;
    let span = p.sdyn_velocity - p.linear_velocity;
    let u = (s - p.linear_velocity) / span;
    (
        printed(s) - gap_at_end * u,
        -p.decay_rate * (p.static_peak - f_ci) * decay(s) - gap_at_end / span,
    )
}

/// Viscous friction b*v (hydrodynamic regime, 400 N/(m/s) in the thesis's section 4.4):
/// the `F_viscous = b v` of assumption 3 (line 5481), added to [`dry_friction`] by the caller.
pub fn viscous_friction(b: f64, v: f64) -> f64 {
    b * v
}

fn simplified(p: &FrictionParams, v: f64) -> f64 {
    let x = v / p.stribeck_velocity;
    // (4.13)
    (p.coulomb + (p.static_peak - p.coulomb) * (-p.stribeck_shape * x.abs()).exp()) * x.tanh()
}

/// Sidhom law for a speed `s >= 0`, equations (4.9)-(4.12).
fn sidhom_positive(p: &FrictionParams, s: f64, accelerating: bool) -> f64 {
    let f_c2 = p.coulomb;
    if s < p.linear_velocity {
        // (4.9), K+ fixed by continuity with (4.10) at v0+.
        p.static_peak / p.linear_velocity * s
    } else if s < p.sdyn_velocity {
        stribeck_decay(p, s, accelerating).0
    } else {
        // (4.11) up to v_max~; beyond it (4.12) is purely viscous, i.e. the caller's b v,
        // so the dry part keeps its v_max~ value.
        f_c2 + p.mixed_slope * (s.min(p.viscous_velocity) - p.sdyn_velocity)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sidhom() -> FrictionParams {
        FrictionParams {
            law: FrictionLaw::Sidhom,
            // A non-zero mixed slope exercises the (4.11)/(4.12) join.
            mixed_slope: 50.0,
            ..FrictionParams::default()
        }
    }

    fn all_cases() -> Vec<(FrictionParams, bool)> {
        let simple = FrictionParams::default();
        vec![
            (simple, true),
            (simple, false),
            (sidhom(), true),
            (sidhom(), false),
        ]
    }

    /// Largest |dF/dv| of the defaults is the (4.9) slope F_sdyn / v0+ = 2000 N/(m/s).
    const LIPSCHITZ_BOUND: f64 = 3000.0;

    #[test]
    fn defaults_are_valid() {
        FrictionParams::default().validate().unwrap();
        sidhom().validate().unwrap();
        let bad = FrictionParams {
            sdyn_velocity: 0.005,
            ..FrictionParams::default()
        };
        assert!(bad.validate().is_err());
    }

    #[test]
    fn continuous_across_every_region_boundary() {
        for (p, acc) in all_cases() {
            let mut boundaries = vec![0.0, p.stribeck_velocity];
            if p.law == FrictionLaw::Sidhom {
                boundaries.extend([p.linear_velocity, p.sdyn_velocity, p.viscous_velocity]);
            }
            for b in boundaries.iter().flat_map(|&b| [b, -b]) {
                for h in [1e-6, 1e-9, 1e-12] {
                    let jump = dry_friction(&p, b + h, acc) - dry_friction(&p, b - h, acc);
                    assert!(
                        jump.abs() <= LIPSCHITZ_BOUND * 2.0 * h + 1e-12,
                        "{:?} acc={acc}: jump {jump} N at v={b} (h={h})",
                        p.law
                    );
                }
            }
        }
    }

    #[test]
    fn continuous_on_a_fine_grid() {
        let dv = 1e-6;
        for (p, acc) in all_cases() {
            let mut prev = dry_friction(&p, -0.2, acc);
            for i in 1..=400_000 {
                let v = -0.2 + f64::from(i) * dv;
                let f = dry_friction(&p, v, acc);
                assert!(
                    (f - prev).abs() <= LIPSCHITZ_BOUND * dv,
                    "{:?} acc={acc}: step {} N at v={v}",
                    p.law,
                    f - prev
                );
                prev = f;
            }
        }
    }

    #[test]
    fn zero_at_rest_positive_forward_and_odd() {
        for (p, acc) in all_cases() {
            assert_eq!(dry_friction(&p, 0.0, acc), 0.0);
            for i in 1..2000 {
                let v = f64::from(i) * 1e-4;
                let f = dry_friction(&p, v, acc);
                assert!(f > 0.0, "{:?}: F({v}) = {f}", p.law);
                assert_eq!(dry_friction(&p, -v, acc), -f);
            }
        }
    }

    #[test]
    fn finite_for_extreme_velocities() {
        for (p, acc) in all_cases() {
            for v in [1e-300, 1e3, -1e3, 1e300, -1e300, f64::MAX] {
                let f = dry_friction(&p, v, acc);
                assert!(
                    f.is_finite() && f.abs() <= 2.0 * p.static_peak,
                    "F({v}) = {f}"
                );
            }
        }
    }

    #[test]
    fn simplified_law_peaks_near_the_stribeck_velocity() {
        let p = FrictionParams::default();
        let (v_peak, f_peak) = (1..20_000)
            .map(|i| f64::from(i) * 1e-5)
            .map(|v| (v, dry_friction(&p, v, true)))
            .fold((0.0, f64::MIN), |a, b| if b.1 > a.1 { b } else { a });
        let v0 = p.stribeck_velocity;
        assert!(v_peak > v0 && v_peak < 3.0 * v0, "peak at {v_peak} m/s");
        // A genuine Stribeck hump: above the Coulomb level, below F_sdyn, decaying back.
        assert!(f_peak > p.coulomb + 0.2 * (p.static_peak - p.coulomb));
        assert!(f_peak < p.static_peak);
        assert!((dry_friction(&p, 40.0 * v0, true) - p.coulomb).abs() < 1e-3);
    }

    #[test]
    fn simplified_law_ignores_the_branch() {
        let p = FrictionParams::default();
        for v in [-0.1, -0.02, 0.003, 0.05, 0.3] {
            assert_eq!(dry_friction(&p, v, true), dry_friction(&p, v, false));
        }
    }

    #[test]
    fn sidhom_branches_differ_only_inside_the_stribeck_zone() {
        let p = sidhom();
        let mid = 0.5 * (p.linear_velocity + p.sdyn_velocity);
        for v in [mid, -mid] {
            let gap = (dry_friction(&p, v, true) - dry_friction(&p, v, false)) * v.signum();
            assert!(gap > 0.25 * p.hysteresis, "gap {gap} N at {v}");
        }
        for v in [
            0.005,
            p.linear_velocity,
            p.sdyn_velocity,
            0.06,
            0.5,
            -0.005,
            -0.5,
        ] {
            assert!((dry_friction(&p, v, true) - dry_friction(&p, v, false)).abs() < 1e-12);
        }
    }

    #[test]
    fn sidhom_peak_and_high_speed_levels() {
        let p = sidhom();
        let peak = dry_friction(&p, p.linear_velocity, false);
        assert!((peak - p.static_peak).abs() < 1e-9);
        let f_end = p.coulomb + p.mixed_slope * (p.viscous_velocity - p.sdyn_velocity);
        assert!((dry_friction(&p, p.sdyn_velocity, true) - p.coulomb).abs() < 1e-9);
        assert!((dry_friction(&p, 1.0, true) - f_end).abs() < 1e-9);
    }

    #[test]
    fn default_small_signal_gain_matches_printed_damping_ratio() {
        // Section 4.3, line 5651: omega_n = 1833 rad/s, xi_v = 0.04 (two significant digits),
        // M = 5.8 kg; the leakage term K_hyd K_lk is about 0.4 1/s and is neglected.
        let p = FrictionParams::default();
        let h = 1e-7;
        let slope = (dry_friction(&p, h, true) - dry_friction(&p, -h, true)) / (2.0 * h);
        assert!((slope - p.static_peak / p.stribeck_velocity).abs() < 1e-3);
        let k_fr = (THESIS_VISCOUS_COEFFICIENT + slope) / 5.8;
        let xi = k_fr / (2.0 * 1833.0);
        assert!((xi - 0.04).abs() < 0.005, "xi = {xi}");
    }

    #[test]
    fn viscous_is_linear_and_odd() {
        assert_eq!(viscous_friction(THESIS_VISCOUS_COEFFICIENT, 0.1), 40.0);
        assert_eq!(viscous_friction(THESIS_VISCOUS_COEFFICIENT, -0.1), -40.0);
    }

    #[test]
    fn deserialises_partial_toml_and_rejects_unknown_fields() {
        let p: FrictionParams = toml::from_str("law = \"sidhom\"\ncoulomb = 12.0").unwrap();
        assert_eq!(p.law, FrictionLaw::Sidhom);
        assert_eq!(p.coulomb, 12.0);
        assert_eq!(p.static_peak, DEFAULT_STATIC_PEAK);
        assert!(toml::from_str::<FrictionParams>("coulumb = 12.0").is_err());
    }
}
