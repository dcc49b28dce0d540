//! Double-rod actuator (section 4.1): two compressible chambers and the moving mass.

use crate::effects::Effect;
use crate::fluid::FluidParams;
use crate::friction::{dry_friction, viscous_friction, FrictionParams};
use crate::params::Params;
use crate::params::GRAVITY;

// The oil's stiffness and its cavitation clamp are properties of the fluid (`fluid`); they
// stay reachable here for the component FMUs in fmu/src/models.
pub use crate::fluid::{cavitation_factor, oil_stiffness, CAVITATION_BAND, CAVITATION_PRESSURE};

/// The fluid as the model uses it, [`Params::fluid_in_use`] (kept under this name for the
/// component FMUs).
pub fn fluid_in_use(p: &Params) -> FluidParams {
    p.fluid_in_use()
}

/// Smallest chamber volume the model accepts, as a fraction of the dead volume. The end
/// stops keep the piston within a fraction of a millimetre of the stroke ends, so this
/// floor is never reached in a physical run; it only keeps trial states of the
/// integrator from dividing by a vanishing volume.
pub const MIN_VOLUME_FRACTION: f64 = 0.1;

/// End-stop contact stiffness (N/m): steel on steel through the rod, stiff enough that
/// the full 210 bar force (about 20 kN) compresses it by only 0.2 mm.
pub const END_STOP_STIFFNESS: f64 = 1e8;

/// End-stop contact damping (N.s/m): near-critical for the 5.8 kg piston on that
/// stiffness (2*sqrt(k*m) = 4.8e4), so the piston does not bounce off the stop.
pub const END_STOP_DAMPING: f64 = 4.8e4;

/// The actuator as the bench assembles it.
#[derive(Debug, Clone)]
pub struct Actuator {
    pub area: f64,
    pub stroke: f64,
    pub dead_volume: f64,
    /// Oil volume merged into each chamber from the manifold (m3).
    pub extra_volume: [f64; 2],
    /// Mass accelerated by the net force: piston, payload and lumped fluid mass (kg).
    pub inertial_mass: f64,
    /// Mass that weighs on the piston: piston and payload (kg).
    pub weight_mass: f64,
    /// Q12 = K (P1 - P2) (m3/s/Pa), (4.1)
    pub internal_leakage: f64,
    /// Qif = K (Pi - PT) (m3/s/Pa), (4.1)
    pub external_leakage: f64,
    pub viscous: f64,
    pub friction: Option<FrictionParams>,
}

/// Forces and acceleration at one state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion {
    pub acceleration: f64,
    pub friction: f64,
}

impl Actuator {
    /// The actuator of a parameter set, with the oil volume and fluid mass the manifold
    /// merges into it. Laminar leakage scales with 1/mu and the hydrostatic bearings'
    /// viscous friction with mu (A.14)-(A.16).
    pub fn from_params(p: &Params, extra_volume: [f64; 2], added_mass: f64) -> Actuator {
        let on = |e: Effect| p.has(e);
        let mu_ratio = p.fluid_in_use().viscosity_ratio();
        let a = &p.actuator;
        let payload = if on(Effect::Payload) {
            a.payload_mass
        } else {
            0.0
        };
        let leak = on(Effect::InternalLeakage);
        Actuator {
            area: a.area,
            stroke: a.stroke,
            dead_volume: a.dead_volume,
            extra_volume,
            inertial_mass: a.mass + payload + added_mass,
            weight_mass: a.mass + payload,
            internal_leakage: if leak {
                a.internal_leakage / mu_ratio
            } else {
                0.0
            },
            external_leakage: if leak {
                a.external_leakage / mu_ratio
            } else {
                0.0
            },
            viscous: if on(Effect::ViscousFriction) {
                a.viscous_friction * mu_ratio
            } else {
                0.0
            },
            friction: on(Effect::DryFriction).then_some(p.friction),
        }
    }

    /// (4.2) chamber volumes, measured from mid stroke: V_i = V_dead + A (stroke/2 +- y).
    pub fn chamber_volumes(&self, y: f64) -> [f64; 2] {
        let half = 0.5 * self.stroke;
        let floor = MIN_VOLUME_FRACTION * self.dead_volume;
        [
            (self.dead_volume + self.area * (half + y)).max(floor) + self.extra_volume[0],
            (self.dead_volume + self.area * (half - y)).max(floor) + self.extra_volume[1],
        ]
    }

    /// Chamber pressures at rest between supply and tank: half the supply pressure,
    /// split so that their difference carries the piston's weight (4.16).
    pub fn rest_pressures(&self, supply: f64, tank: f64) -> [f64; 2] {
        let mid = 0.5 * (supply + tank);
        let hold = self.weight_mass * GRAVITY / self.area;
        [mid + 0.5 * hold, mid - 0.5 * hold]
    }

    /// Contact force of the end stops (N), zero inside the stroke.
    pub fn end_stop_force(&self, y: f64, v: f64) -> f64 {
        let half = 0.5 * self.stroke;
        if y > half {
            -END_STOP_STIFFNESS * (y - half) - END_STOP_DAMPING * v.max(0.0)
        } else if y < -half {
            END_STOP_STIFFNESS * (-half - y) - END_STOP_DAMPING * v.min(0.0)
        } else {
            0.0
        }
    }

    /// (4.4) M d2y/dt2 = A (P1 - P2) - M g - F_fric - F_ext (+ end stops). The fluid
    /// inertia term F_fluid of (4.4) is carried either by the manifold passages or by the
    /// lumped fluid mass in `inertial_mass`; fluid weight in the chambers is neglected
    /// (a few grams of oil against 5.8 kg).
    pub fn motion(&self, y: f64, v: f64, p: [f64; 2], f_ext: f64) -> Motion {
        let driving = self.area * (p[0] - p[1]) - self.weight_mass * GRAVITY - f_ext
            + self.end_stop_force(y, v);
        let mut friction = viscous_friction(self.viscous, v);
        if let Some(fp) = &self.friction {
            // The Sidhom branches depend on the sign of the acceleration, which friction
            // itself changes: the sign of the force that drives the motion decides
            // instead, so friction stays an explicit function of the state.
            friction += dry_friction(fp, v, driving * v > 0.0);
        }
        Motion {
            acceleration: (driving - friction) / self.inertial_mass,
            friction,
        }
    }

    /// (4.1) chamber pressure derivatives for the flows `q_in` delivered into the chambers:
    /// leakages and the piston's displacement flow, over the chambers' compliance.
    pub fn pressure_derivatives(
        &self,
        y: f64,
        v: f64,
        p: [f64; 2],
        q_in: [f64; 2],
        p_tank: f64,
        stiffness: impl Fn(f64) -> f64,
    ) -> [f64; 2] {
        let (q12, qf) = self.leakage(p, p_tank);
        let vol = self.chamber_volumes(y);
        [
            stiffness(p[0]) / vol[0] * (q_in[0] - q12 - qf[0] - self.area * v),
            stiffness(p[1]) / vol[1] * (q_in[1] + q12 - qf[1] + self.area * v),
        ]
    }

    /// (4.1) leakage flows: piston (chamber 1 to 2) and each chamber to the drain.
    pub fn leakage(&self, p: [f64; 2], p_tank: f64) -> (f64, [f64; 2]) {
        (
            self.internal_leakage * (p[0] - p[1]),
            [
                self.external_leakage * (p[0] - p_tank),
                self.external_leakage * (p[1] - p_tank),
            ],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn actuator() -> Actuator {
        Actuator {
            area: 9.456e-4,
            stroke: 0.3,
            dead_volume: 14.184e-6,
            extra_volume: [0.0; 2],
            inertial_mass: 5.8,
            weight_mass: 5.8,
            internal_leakage: 0.0,
            external_leakage: 0.0,
            viscous: 0.0,
            friction: None,
        }
    }

    #[test]
    fn mid_stroke_volume_is_the_thesis_value() {
        let v = actuator().chamber_volumes(0.0);
        assert!((v[0] - 1.56e-4).abs() < 1e-7 && v[0] == v[1]);
        let end = actuator().chamber_volumes(-0.15);
        assert!((end[0] - 14.184e-6).abs() < 1e-12);
    }

    #[test]
    fn volumes_stay_positive_beyond_the_stops() {
        for y in [-1.0, -0.2, 0.2, 1.0] {
            assert!(actuator().chamber_volumes(y).iter().all(|v| *v > 0.0));
        }
    }

    #[test]
    fn hanging_piston_needs_weight_over_area() {
        let a = actuator();
        let dp = a.weight_mass * GRAVITY / a.area;
        let m = a.motion(0.0, 0.0, [100e5 + dp, 100e5], 0.0);
        assert!(m.acceleration.abs() < 1e-9);
    }

    #[test]
    fn end_stop_pushes_back_and_cavitation_factor_is_a_smooth_clamp() {
        let a = actuator();
        assert!(a.end_stop_force(0.1501, 0.0) < 0.0 && a.end_stop_force(-0.1501, 0.0) > 0.0);
        assert_eq!(a.end_stop_force(0.1, 1.0), 0.0);
        assert_eq!(cavitation_factor(CAVITATION_PRESSURE - 1.0), 0.0);
        assert_eq!(
            cavitation_factor(CAVITATION_PRESSURE + CAVITATION_BAND),
            1.0
        );
        assert!(cavitation_factor(CAVITATION_PRESSURE + 0.5 * CAVITATION_BAND) == 0.5);
    }
}
