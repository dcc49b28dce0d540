//! One description of a controller as the thesis's experiments configure it: the law,
//! its gains, where its state estimate comes from, and the model it believes in.

use serde::{Deserialize, Serialize};

use super::backstepping::{Gains, YLambda, PY};
use super::law::{ControlModel, Estimate, Law, Reference};
use super::model_free::{ModelFree, RestrictedModel};
use super::sampled::{SampledController, StateSource, DAO2_GAINS};
use super::{Proportional, SAMPLE_PERIOD};
use crate::params::Params;

/// The control laws of chapters 4 to 6.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LawKind {
    /// u1 = -u2 = Kp (y_d - y), (4.22)
    Proportional,
    /// Backstepping Y-lambda, (5.16)-(5.35)
    YLambda,
    /// Backstepping P-Y, (5.36)-(5.58)
    PY,
    /// Model-free i-PI, (6.6)-(6.9)
    ModelFree,
    /// Control with restricted model, (6.10)-(6.17)
    RestrictedModel,
}

impl LawKind {
    pub const ALL: [LawKind; 5] = [
        LawKind::Proportional,
        LawKind::YLambda,
        LawKind::PY,
        LawKind::ModelFree,
        LawKind::RestrictedModel,
    ];
}

/// A controller as configured for an experiment.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerParams {
    pub law: LawKind,
    /// Proportional gain of (4.22) (V/m); 1169 in section 4.4, 5200 in Table 5.1.
    pub kp: f64,
    /// Backstepping gains c1..c4 (1/s).
    pub c: [f64; 4],
    /// Weight of the Y-lambda pressure combination.
    pub lambda: f64,
    /// Proportional gain of the model-free and restricted-model laws (V/m).
    pub kp_model_free: f64,
    /// Where the velocity and acceleration estimates come from.
    pub source: StateSource,
    /// DAO2 gains Kd0, Kd1 (1/s).
    pub dao2: [f64; 2],
    /// Sampling period (s).
    pub period: f64,
    /// Time from a sample to its command reaching the valves (s).
    pub computation_delay: f64,
}

impl Default for ControllerParams {
    fn default() -> Self {
        let g = Gains::HIGH_Y_LAMBDA;
        ControllerParams {
            law: LawKind::Proportional,
            kp: 1169.0,
            c: [g.c1, g.c2, g.c3, g.c4],
            lambda: super::backstepping::LAMBDA_THESIS,
            kp_model_free: super::model_free::KP_LOW,
            source: StateSource::Dao2,
            dao2: DAO2_GAINS,
            period: SAMPLE_PERIOD,
            computation_delay: 0.0,
        }
    }
}

impl ControlModel {
    /// The control model (II.1)-(II.2) of a bench parameter set, as a controller designer
    /// would write it: nominal moving mass without payload, mid-stroke volumes, the
    /// liquid's bulk modulus, and the valve's catalogue flow gain (one land metering the
    /// rated flow at half the rated drop, as the plant's valve model does).
    pub fn from_params(p: &Params) -> ControlModel {
        let a = &p.actuator;
        ControlModel {
            area: a.area,
            mass: a.mass,
            bulk_modulus: p.fluid.bulk_modulus,
            v0: a.dead_volume + a.area * 0.5 * a.stroke,
            viscous: a.viscous_friction,
            supply: p.supply_pressure,
            tank: p.tank_pressure,
            flow_per_volt: p.sv1.rated_flow / p.sv1.rated_command,
            rated_drop: 0.5 * p.sv1.rated_pressure_drop,
        }
    }
}

/// Any law of the thesis, as a plain value: cloned and serialized with the controller
/// state for the FMUs' get/set/serialize state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum AnyLaw {
    Proportional(Proportional),
    YLambda(YLambda),
    PY(PY),
    ModelFree(ModelFree),
    RestrictedModel(RestrictedModel),
}

impl AnyLaw {
    fn inner(&mut self) -> &mut dyn Law {
        match self {
            AnyLaw::Proportional(l) => l,
            AnyLaw::YLambda(l) => l,
            AnyLaw::PY(l) => l,
            AnyLaw::ModelFree(l) => l,
            AnyLaw::RestrictedModel(l) => l,
        }
    }
}

impl Law for AnyLaw {
    fn commands(&mut self, t: f64, r: &Reference, x: &Estimate, period: f64) -> [f64; 2] {
        self.inner().commands(t, r, x, period)
    }
    fn reset(&mut self) {
        self.inner().reset()
    }
}

impl ControllerParams {
    pub fn law(&self, model: ControlModel) -> AnyLaw {
        let [c1, c2, c3, c4] = self.c;
        let gains = Gains { c1, c2, c3, c4 };
        match self.law {
            LawKind::Proportional => AnyLaw::Proportional(Proportional { kp: self.kp }),
            LawKind::YLambda => AnyLaw::YLambda(YLambda::new(model, gains, self.lambda)),
            LawKind::PY => AnyLaw::PY(PY::new(model, gains)),
            LawKind::ModelFree => AnyLaw::ModelFree(ModelFree::thesis(self.kp_model_free)),
            LawKind::RestrictedModel => {
                AnyLaw::RestrictedModel(RestrictedModel::thesis(model, self.kp_model_free))
            }
        }
    }

    /// The sampled controller for a bench parameter set.
    pub fn controller(&self, bench: &Params) -> SampledController {
        SampledController::new(
            self.law(ControlModel::from_params(bench)),
            self.source,
            self.dao2,
            self.period,
        )
    }
}
