//! One FMU instance: the FMI 2.0 Co-Simulation state machine around a [`Model`] and
//! the state snapshots; the host's logger is in `logger`. Nothing here knows any physics.

use std::ffi::{c_char, CStr};

use sha2::{Digest, Sha256};

use crate::ffi::Status;
use crate::slave::{Model, Value, VarDef};

mod logger;

pub use crate::ffi::LOG_CATEGORIES;
pub use logger::Logger;

/// FMI 2.0 Co-Simulation states (standard section 4.2.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum State {
    Instantiated,
    InitializationMode,
    StepComplete,
    StepFailed,
    Terminated,
    Error,
}

/// The operations the exported functions need, whatever the model.
pub trait Component: Send {
    fn logger(&mut self) -> &mut Logger;
    fn state(&self) -> State;
    fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: Option<f64>)
        -> Status;
    fn enter_initialization(&mut self) -> Status;
    fn exit_initialization(&mut self) -> Status;
    fn terminate(&mut self) -> Status;
    fn reset(&mut self) -> Status;
    fn get(&mut self, vr: u32, want: Kind) -> Result<Value, (Status, String)>;
    fn set(&mut self, vr: u32, value: Value) -> Result<(), (Status, String)>;
    fn do_step(&mut self, t: f64, h: f64) -> Status;
    fn time(&self) -> f64;
    fn get_state(&mut self) -> Result<Box<dyn std::any::Any + Send>, (Status, String)>;
    fn set_state(&mut self, s: &(dyn std::any::Any + Send)) -> Status;
    fn serialize(&mut self, s: &(dyn std::any::Any + Send)) -> Result<Vec<u8>, (Status, String)>;
    fn deserialize(
        &mut self,
        bytes: &[u8],
    ) -> Result<Box<dyn std::any::Any + Send>, (Status, String)>;
}

/// The base type a get/set call asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Real,
    Integer,
    Boolean,
}

pub struct Instance<M: Model> {
    model: M,
    vars: Vec<VarDef<M>>,
    state: State,
    pub log: Logger,
    resources: Option<std::path::PathBuf>,
    /// The master's clock: the models run on time since `start_time` (0 at
    /// initialization), so that a start at t0 = 1.7e9 s integrates exactly as one at 0
    /// (issue 16, item 5); `clock` is the master's time of the model's current instant.
    start_time: f64,
    clock: f64,
    stop_time: Option<f64>,
}

/// A complete FMU state: the model's and the instance's (life-cycle state and clock),
/// so a state restored from bytes resumes exactly where and as the saved one was.
#[derive(Clone, serde::Serialize, serde::Deserialize)]
pub struct Saved<S> {
    state: State,
    start_time: f64,
    clock: f64,
    model: S,
}

/// Magic and version of a serialized state: anything else is refused. Version 2 holds
/// the life-cycle state and the clock besides the model's state.
const STATE_MAGIC: &[u8; 8] = b"HBSTATE2";

/// Communication points may differ from the instance's clock by rounding: a master that
/// computes t0 + n h instead of summing steps lands a few ulps off. This many ulps of the
/// time, plus 1e-9 of the elapsed time, are accepted; at t0 = 1e9 s that is 3.6 us.
const CLOCK_ULPS: f64 = 16.0;

impl<M: Model> Instance<M> {
    /// A new instance; on failure the logger comes back so the caller can report.
    pub fn new(
        log: Logger,
        resources: Option<std::path::PathBuf>,
    ) -> Result<Self, (Logger, String)> {
        let model = match M::instantiate(resources.as_deref()) {
            Ok(m) => m,
            Err(e) => return Err((log, e)),
        };
        Ok(Instance {
            model,
            vars: M::variables(),
            state: State::Instantiated,
            log,
            resources,
            start_time: 0.0,
            clock: 0.0,
            stop_time: None,
        })
    }

    /// The first Real output that is not a finite number, as a message.
    fn non_finite_output(&self) -> Option<String> {
        self.vars.iter().find_map(|var| {
            if var.decl.causality != modeldesc::Causality::Output {
                return None;
            }
            match (var.get)(&self.model) {
                Value::Real(x) if !x.is_finite() => {
                    Some(format!("output {} is {x}", var.decl.name))
                }
                _ => None,
            }
        })
    }

    /// Refuse to go on with a non-finite output: no call answers fmi2OK with one.
    fn guard_outputs(&mut self, call: &str) -> Status {
        match self.non_finite_output() {
            None => Status::Ok,
            Some(what) => self.fail(
                Status::Error,
                format!("{call}: {what}; the instance is in the error state (set a saved FMU state to go on)"),
            ),
        }
    }

    /// Restore `saved` into a fresh model of the same resources, refusing any content
    /// the model does not accept or that gives non-finite outputs: a checksum proves
    /// only that the bytes are the ones written, not that they make a valid state.
    fn check_content(&self, saved: &Saved<M::Snapshot>) -> Result<(), String> {
        let finite_clock = saved.start_time.is_finite()
            && saved.clock.is_finite()
            && saved.clock >= saved.start_time;
        if !finite_clock || saved.state == State::Error {
            return Err(format!(
                "impossible life cycle or clock ({:?}, start {}, clock {})",
                saved.state, saved.start_time, saved.clock
            ));
        }
        let snap = saved.model.clone();
        let resources = self.resources.clone();
        let trial = std::panic::catch_unwind(std::panic::AssertUnwindSafe(
            move || -> Result<Option<String>, String> {
                let mut m = M::instantiate(resources.as_deref())?;
                m.restore(snap)?;
                if !m.time().is_finite() || m.time() < 0.0 {
                    return Err(format!(
                        "model time {} is not a time since the start",
                        m.time()
                    ));
                }
                let vars = M::variables();
                Ok(vars.iter().find_map(|var| match (var.get)(&m) {
                    Value::Real(x)
                        if var.decl.causality == modeldesc::Causality::Output && !x.is_finite() =>
                    {
                        Some(format!("output {} would be {x}", var.decl.name))
                    }
                    _ => None,
                }))
            },
        ));
        match trial {
            Ok(Ok(None)) => Ok(()),
            Ok(Ok(Some(why))) | Ok(Err(why)) => Err(why),
            Err(_) => Err("the model cannot hold this content (internal check failed)".into()),
        }
    }

    fn fail(&mut self, status: Status, message: String) -> Status {
        self.log.error(&message);
        if status >= Status::Error {
            self.state = State::Error;
        }
        status
    }

    fn require(&mut self, allowed: &[State], call: &str) -> Result<(), Status> {
        if allowed.contains(&self.state) {
            Ok(())
        } else {
            let st = self.state;
            Err(self.fail(
                Status::Error,
                format!("{call} is not allowed in state {st:?}"),
            ))
        }
    }
}

fn kind_of(v: &Value) -> Kind {
    match v {
        Value::Real(_) => Kind::Real,
        Value::Integer(_) => Kind::Integer,
        Value::Boolean(_) => Kind::Boolean,
    }
}

fn declared_kind(k: &modeldesc::VarKind) -> Option<Kind> {
    match k {
        modeldesc::VarKind::Real { .. } => Some(Kind::Real),
        modeldesc::VarKind::Integer { .. } | modeldesc::VarKind::Enumeration { .. } => {
            Some(Kind::Integer)
        }
        modeldesc::VarKind::Boolean { .. } => Some(Kind::Boolean),
        modeldesc::VarKind::String { .. } => None,
    }
}

impl<M: Model> Component for Instance<M> {
    fn logger(&mut self) -> &mut Logger {
        &mut self.log
    }

    fn state(&self) -> State {
        self.state
    }

    fn setup_experiment(
        &mut self,
        tolerance: Option<f64>,
        start: f64,
        stop: Option<f64>,
    ) -> Status {
        if let Err(s) = self.require(&[State::Instantiated], "fmi2SetupExperiment") {
            return s;
        }
        if !start.is_finite() || stop.is_some_and(|s| !s.is_finite() || s < start) {
            return self.fail(
                Status::Error,
                format!("invalid experiment interval [{start}, {stop:?}]"),
            );
        }
        if let Some(tol) = tolerance {
            // the registry's bounds of the integrator's relative tolerance
            let (lo, hi) =
                hbmodel::params::param("solver.rtol").map_or((1e-12, 1e-2), |p| (p.min, p.max));
            if !(tol.is_finite() && (lo..=hi).contains(&tol)) {
                return self.fail(
                    Status::Error,
                    format!("fmi2SetupExperiment: tolerance {tol} lies outside [{lo}, {hi}]"),
                );
            }
            match self.model.relative_tolerance() {
                Some(rtol) => *rtol = tol,
                None => self.log.log(
                    Status::Ok,
                    2,
                    &format!("tolerance {tol} not used: this model has no integrator"),
                ),
            }
        }
        self.start_time = start;
        self.clock = start;
        self.stop_time = stop;
        Status::Ok
    }

    fn enter_initialization(&mut self) -> Status {
        if let Err(s) = self.require(&[State::Instantiated], "fmi2EnterInitializationMode") {
            return s;
        }
        self.clock = self.start_time;
        match self.model.initialize(0.0) {
            Ok(()) => {
                self.state = State::InitializationMode;
                self.log.log(Status::Ok, 2, "entered initialization mode");
                Status::Ok
            }
            Err(e) => self.fail(Status::Error, format!("cannot initialize: {e}")),
        }
    }

    fn exit_initialization(&mut self) -> Status {
        if let Err(s) = self.require(&[State::InitializationMode], "fmi2ExitInitializationMode") {
            return s;
        }
        // parameters may have changed in initialization mode: refresh takes them in
        match self.model.refresh() {
            Ok(()) => {
                self.state = State::StepComplete;
                self.guard_outputs("fmi2ExitInitializationMode")
            }
            Err(e) => self.fail(Status::Error, format!("cannot initialize: {e}")),
        }
    }

    fn terminate(&mut self) -> Status {
        if let Err(s) = self.require(&[State::StepComplete, State::StepFailed], "fmi2Terminate") {
            return s;
        }
        self.state = State::Terminated;
        self.log.log(Status::Ok, 2, "terminated");
        Status::Ok
    }

    fn reset(&mut self) -> Status {
        match M::instantiate(self.resources.as_deref()) {
            Ok(m) => {
                self.model = m;
                self.state = State::Instantiated;
                self.start_time = 0.0;
                self.clock = 0.0;
                self.stop_time = None;
                Status::Ok
            }
            Err(e) => self.fail(Status::Error, format!("cannot reset: {e}")),
        }
    }

    fn get(&mut self, vr: u32, want: Kind) -> Result<Value, (Status, String)> {
        let Some(var) = self.vars.get(vr as usize) else {
            return Err((Status::Error, format!("unknown value reference {vr}")));
        };
        if declared_kind(&var.decl.kind) != Some(want) {
            return Err((
                Status::Error,
                format!(
                    "value reference {vr} ({}) is not of the requested type {want:?}",
                    var.decl.name
                ),
            ));
        }
        if var.decl.causality == modeldesc::Causality::Output && self.state == State::Instantiated {
            return Err((
                Status::Error,
                format!(
                    "output {} has no value before initialization mode",
                    var.decl.name
                ),
            ));
        }
        if self.state == State::Error {
            return Err((Status::Error, "the instance is in the error state".into()));
        }
        if var.decl.causality == modeldesc::Causality::Output {
            self.model.refresh().map_err(|e| (Status::Error, e))?;
            if let Value::Real(x) = (var.get)(&self.model) {
                if !x.is_finite() {
                    self.state = State::Error;
                    return Err((
                        Status::Error,
                        format!(
                            "output {} is {x}; the instance is in the error state",
                            var.decl.name
                        ),
                    ));
                }
            }
        }
        Ok((var.get)(&self.model))
    }

    fn set(&mut self, vr: u32, value: Value) -> Result<(), (Status, String)> {
        use modeldesc::Causality as C;
        let Some(var) = self.vars.get(vr as usize) else {
            return Err((Status::Error, format!("unknown value reference {vr}")));
        };
        if declared_kind(&var.decl.kind) != Some(kind_of(&value)) {
            return Err((
                Status::Error,
                format!(
                    "value reference {vr} ({}) is not of the given type",
                    var.decl.name
                ),
            ));
        }
        let allowed = match var.decl.causality {
            C::Input => matches!(
                self.state,
                State::Instantiated | State::InitializationMode | State::StepComplete
            ),
            C::Parameter => matches!(self.state, State::Instantiated | State::InitializationMode),
            _ => false,
        };
        if !allowed {
            return Err((
                Status::Error,
                format!(
                    "{} ({:?}) cannot be set in state {:?}",
                    var.decl.name, var.decl.causality, self.state
                ),
            ));
        }
        let Some(set) = &var.set else {
            return Err((Status::Error, format!("{} cannot be set", var.decl.name)));
        };
        set(&mut self.model, value)
            .map_err(|e| (Status::Discard, format!("{}: {e}", var.decl.name)))
    }

    fn do_step(&mut self, t: f64, h: f64) -> Status {
        if let Err(s) = self.require(&[State::StepComplete], "fmi2DoStep") {
            return s;
        }
        let now = self.clock;
        if h.is_nan() || h <= 0.0 || !h.is_finite() || !t.is_finite() {
            return self.fail(Status::Error, format!("invalid step: t = {t}, h = {h}"));
        }
        let slack = CLOCK_ULPS * f64::EPSILON * now.abs() + 1e-9 * (now - self.start_time).max(1.0);
        if (t - now).abs() > slack {
            return self.fail(
                Status::Error,
                format!("fmi2DoStep at t = {t} but the instance is at t = {now}"),
            );
        }
        match self.model.do_step(h).and_then(|_| self.model.refresh()) {
            Ok(()) => {
                self.clock = t + h;
                self.guard_outputs("fmi2DoStep")
            }
            Err(e) => {
                // the model keeps its state at t; the master may retry with a smaller step
                self.state = State::StepFailed;
                self.log.log(
                    Status::Discard,
                    0,
                    &format!("step from t = {t} by {h} s failed: {e}"),
                );
                Status::Discard
            }
        }
    }

    fn time(&self) -> f64 {
        self.clock
    }

    fn get_state(&mut self) -> Result<Box<dyn std::any::Any + Send>, (Status, String)> {
        if matches!(self.state, State::Error) {
            return Err((Status::Error, "no state to get in the error state".into()));
        }
        Ok(Box::new(Saved {
            state: self.state,
            start_time: self.start_time,
            clock: self.clock,
            model: self.model.snapshot(),
        }))
    }

    fn set_state(&mut self, s: &(dyn std::any::Any + Send)) -> Status {
        let Some(saved) = s.downcast_ref::<Saved<M::Snapshot>>() else {
            return self.fail(
                Status::Error,
                "the FMU state belongs to another model".into(),
            );
        };
        match self.model.restore(saved.model.clone()) {
            Ok(()) => {
                self.state = if saved.state == State::StepFailed {
                    State::StepComplete
                } else {
                    saved.state
                };
                self.start_time = saved.start_time;
                self.clock = saved.clock;
                Status::Ok
            }
            Err(e) => self.fail(Status::Error, format!("cannot restore the state: {e}")),
        }
    }

    fn serialize(&mut self, s: &(dyn std::any::Any + Send)) -> Result<Vec<u8>, (Status, String)> {
        let Some(saved) = s.downcast_ref::<Saved<M::Snapshot>>() else {
            return Err((
                Status::Error,
                "the FMU state belongs to another model".into(),
            ));
        };
        let body = serde_json::to_vec(saved).map_err(|e| (Status::Error, e.to_string()))?;
        let mut out = Vec::with_capacity(body.len() + 48);
        out.extend_from_slice(STATE_MAGIC);
        out.extend_from_slice(M::info().model_identifier.as_bytes());
        out.push(0);
        out.extend_from_slice(&(body.len() as u64).to_le_bytes());
        out.extend_from_slice(&Sha256::digest(&body)[..16]);
        out.extend_from_slice(&body);
        Ok(out)
    }

    fn deserialize(
        &mut self,
        bytes: &[u8],
    ) -> Result<Box<dyn std::any::Any + Send>, (Status, String)> {
        let bad = |why: &str| {
            (
                Status::Error,
                format!("not a serialized state of this FMU: {why}"),
            )
        };
        let rest = bytes
            .strip_prefix(STATE_MAGIC.as_slice())
            .ok_or_else(|| bad("wrong magic or version"))?;
        let id = M::info().model_identifier.as_bytes();
        let rest = rest
            .strip_prefix(id)
            .and_then(|r| r.strip_prefix(&[0u8]))
            .ok_or_else(|| bad("written by another model"))?;
        if rest.len() < 24 {
            return Err(bad("truncated"));
        }
        let len = u64::from_le_bytes(rest[..8].try_into().unwrap_or([0; 8])) as usize;
        let (sum, body) = rest[8..].split_at(16);
        if body.len() != len || Sha256::digest(body)[..16] != *sum {
            return Err(bad("length or checksum mismatch"));
        }
        let saved: Saved<M::Snapshot> =
            serde_json::from_slice(body).map_err(|e| bad(&e.to_string()))?;
        self.check_content(&saved).map_err(|why| bad(&why))?;
        Ok(Box::new(saved))
    }
}

/// Read a C string argument, refusing NULL.
///
/// # Safety
/// `p` must be null or a valid NUL-terminated string.
pub unsafe fn c_str<'a>(p: *const c_char) -> Option<&'a str> {
    if p.is_null() {
        None
    } else {
        CStr::from_ptr(p).to_str().ok()
    }
}
