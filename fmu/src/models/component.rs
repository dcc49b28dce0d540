//! The one generic component FMU: a [`CosimUnit`] of the model behind the shim, built
//! lazily from the parameters, integrated over each step with the components' one
//! tolerance policy, snapshotted and restored. Each component FMU is a small
//! [`Declaration`] (servovalve.rs, manifold.rs, actuator.rs): its variables, mapped by
//! position onto the unit's inputs and outputs, and which unit its parameters build.

use std::marker::PhantomData;
use std::path::Path;

use hbmodel::component::cosim::{check_state, CosimUnit};
use hbmodel::component::tolerances;
use hbmodel::solver::{integrate, SolverStats, Tolerances};
use hbmodel::Params;
use serde::{Deserialize, Serialize};

use super::{load_params, HasParams};
use crate::slave::{real_input, real_output, Model, ModelInfo, VarDef};

/// What makes a component FMU of a [`CosimUnit`].
pub trait Declaration: Sized + Send + 'static {
    fn info() -> ModelInfo;
    /// The built-in parameters (resources/parameters.toml overrides them).
    fn default_params() -> Params;
    /// The unit the parameters ask for (validated parameters).
    fn build(p: &Params) -> Box<dyn CosimUnit>;
    /// The inputs' values on instantiation, for the parameters in use.
    fn start_inputs(p: &Params) -> Vec<f64>;
    fn n_outputs() -> usize;
    fn variables() -> Vec<VarDef<ComponentFmu<Self>>>;
}

/// The complete state of a component FMU.
#[derive(Clone, Serialize, Deserialize)]
pub struct Snapshot {
    params: Params,
    /// The unit's states (empty before initialization).
    x: Vec<f64>,
    inputs: Vec<f64>,
    t: f64,
}

pub struct ComponentFmu<D> {
    s: Snapshot,
    unit: Option<Box<dyn CosimUnit>>,
    out: Vec<f64>,
    _declaration: PhantomData<fn() -> D>,
}

impl<D> HasParams for ComponentFmu<D> {
    fn params(&self) -> &Params {
        &self.s.params
    }
    fn params_mut(&mut self) -> &mut Params {
        self.unit = None;
        &mut self.s.params
    }
}

/// Input `k` of the unit as an FMU input.
pub fn input<D: Declaration>(
    k: usize,
    name: &str,
    description: &str,
    unit: &str,
    start: f64,
    bounds: (Option<f64>, Option<f64>),
) -> VarDef<ComponentFmu<D>> {
    real_input(
        name,
        description,
        unit,
        start,
        bounds,
        move |m: &ComponentFmu<D>| m.input(k),
        move |m, x| m.set_input(k, x),
    )
}

/// Output `k` of the unit as an FMU output.
pub fn output<D: Declaration>(
    k: usize,
    name: &str,
    description: &str,
    unit: &str,
) -> VarDef<ComponentFmu<D>> {
    real_output(name, description, unit, move |m: &ComponentFmu<D>| m.out[k])
}

impl<D: Declaration> ComponentFmu<D> {
    pub fn input(&self, k: usize) -> f64 {
        self.s.inputs[k]
    }

    pub fn set_input(&mut self, k: usize, x: f64) {
        self.s.inputs[k] = x;
    }

    /// The unit, built on first use after a parameter change; a state of the wrong size
    /// (none yet, or another model's) starts at the unit's rest state.
    fn unit(&mut self) -> Result<&dyn CosimUnit, String> {
        if self.unit.is_none() {
            self.s.params.validate().map_err(|e| e.to_string())?;
            let unit = D::build(&self.s.params);
            if self.s.x.len() != unit.states().len() {
                self.s.x = unit.initial_state(&self.s.inputs);
            }
            self.unit = Some(unit);
        }
        self.unit.as_deref().ok_or_else(|| "no model".to_string())
    }
}

impl<D: Declaration> Model for ComponentFmu<D> {
    type Snapshot = Snapshot;

    fn info() -> ModelInfo {
        D::info()
    }

    fn variables() -> Vec<VarDef<Self>> {
        D::variables()
    }

    fn instantiate(resources: Option<&Path>) -> Result<Self, String> {
        let params = load_params(resources, D::default_params())?;
        Ok(ComponentFmu {
            s: Snapshot {
                inputs: D::start_inputs(&params),
                params,
                x: vec![],
                t: 0.0,
            },
            unit: None,
            out: vec![0.0; D::n_outputs()],
            _declaration: PhantomData,
        })
    }

    fn initialize(&mut self, start_time: f64) -> Result<(), String> {
        self.s.t = start_time;
        self.s.x.clear();
        self.unit = None;
        self.refresh()
    }

    fn refresh(&mut self) -> Result<(), String> {
        self.unit()?;
        let unit = self.unit.as_deref().ok_or("no model")?;
        unit.outputs(&self.s.x, &self.s.inputs, &mut self.out);
        Ok(())
    }

    fn do_step(&mut self, h: f64) -> Result<(), String> {
        self.unit()?;
        let unit = self.unit.as_deref().ok_or("no model")?;
        let n = unit.states().len();
        if n > 0 {
            let p = &self.s.params;
            let system = unit.step(&self.s.x, &self.s.inputs);
            let (atol, scale) = tolerances(&system.states, p.solver.rtol);
            let tol = Tolerances {
                rtol: p.solver.rtol,
                atol,
                fixed_step: p.solver.fixed_step,
            };
            let mut x = system.x;
            let rhs = &system.rhs;
            integrate(
                |_t, x, dx| rhs(x, dx),
                &mut x,
                self.s.t,
                self.s.t + h,
                &tol,
                &scale,
                &mut SolverStats::default(),
            )
            .map_err(|e| e.to_string())?;
            x.truncate(n);
            self.s.x = x;
        }
        self.s.t += h;
        Ok(())
    }

    fn time(&self) -> f64 {
        self.s.t
    }

    fn snapshot(&self) -> Snapshot {
        self.s.clone()
    }

    /// A state from bytes must be one the model can be in (issue 16, item 7): its
    /// parameters valid, as many inputs as the model has, its states the unit's size,
    /// finite, with no negative absolute pressure. An empty state is one taken before
    /// initialization.
    fn restore(&mut self, s: Snapshot) -> Result<(), String> {
        let expected = D::start_inputs(&s.params).len();
        if s.inputs.len() != expected {
            return Err(format!("a state of this model has {expected} inputs"));
        }
        if !s.x.is_empty() {
            s.params.validate().map_err(|e| e.to_string())?;
            check_state(D::build(&s.params).as_ref(), &s.x)?;
        }
        self.s = s;
        self.unit = None;
        self.refresh()
    }

    fn relative_tolerance(&mut self) -> Option<&mut f64> {
        Some(&mut self.params_mut().solver.rtol)
    }
}
