//! One FMU instance: the FMI 2.0 Co-Simulation state machine around a [`Model`], the
//! host's logger, and the state snapshots. Nothing here knows any physics.

use std::ffi::{c_char, CStr, CString};

use sha2::{Digest, Sha256};

use crate::ffi::{CallbackFunctions, CallbackLogger, ComponentEnvironment, Status};
use crate::slave::{Model, Value, VarDef};

/// Log categories declared in every model description.
pub const LOG_CATEGORIES: [(&str, &str); 3] = [
    (
        "logStatusError",
        "Errors: misuse of the API, refused values, failed steps",
    ),
    ("logStatusWarning", "Warnings"),
    (
        "logEvents",
        "Life cycle: instantiation, initialization, termination",
    ),
];

/// FMI 2.0 Co-Simulation states (standard section 4.2.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum State {
    Instantiated,
    InitializationMode,
    StepComplete,
    StepFailed,
    Terminated,
    Error,
}

/// The host's logger and identity, kept to report through.
pub struct Logger {
    callback: CallbackLogger,
    environment: ComponentEnvironment,
    instance_name: CString,
    pub logging_on: bool,
    pub categories: Vec<bool>,
}

// The environment pointer is the host's, handed back to it unchanged; the host owns
// thread safety of its own logger (FMI 2.0 allows no concurrent calls on one instance).
unsafe impl Send for Logger {}

impl Logger {
    /// # Safety
    /// `functions` must be null or point to a valid fmi2CallbackFunctions.
    pub unsafe fn new(
        functions: *const CallbackFunctions,
        instance_name: &str,
        logging_on: bool,
    ) -> Logger {
        let (callback, environment) = match functions.as_ref() {
            Some(f) => (f.logger, f.component_environment),
            None => (None, std::ptr::null_mut()),
        };
        Logger {
            callback,
            environment,
            instance_name: CString::new(instance_name.replace('\0', " ")).unwrap_or_default(),
            logging_on,
            categories: vec![true; LOG_CATEGORIES.len()],
        }
    }

    /// Report through the host's callback. Refusals (discard) and errors are always
    /// reported, so every misuse leaves a message; the rest only when logging is on
    /// and the category enabled.
    pub fn log(&self, status: Status, category: usize, message: &str) {
        let Some(cb) = self.callback else { return };
        let forced = status >= Status::Discard;
        if !forced && (!self.logging_on || !self.categories.get(category).copied().unwrap_or(false))
        {
            return;
        }
        let cat = CString::new(LOG_CATEGORIES[category.min(LOG_CATEGORIES.len() - 1)].0)
            .unwrap_or_default();
        let msg = CString::new(message.replace('\0', " ")).unwrap_or_default();
        let fmt = c"%s";
        // SAFETY: the host gave us this logger; the message goes through "%s" so no
        // format directive in it is ever interpreted.
        unsafe {
            cb(
                self.environment,
                self.instance_name.as_ptr(),
                status,
                cat.as_ptr(),
                fmt.as_ptr(),
                msg.as_ptr(),
            )
        };
    }

    pub fn error(&self, message: &str) {
        self.log(Status::Error, 0, message);
    }
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
    start_time: f64,
    stop_time: Option<f64>,
}

/// Magic and version of a serialized state: anything else is refused.
const STATE_MAGIC: &[u8; 8] = b"HBSTATE1";

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
            stop_time: None,
        })
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
        _tolerance: Option<f64>,
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
        self.start_time = start;
        self.stop_time = stop;
        Status::Ok
    }

    fn enter_initialization(&mut self) -> Status {
        if let Err(s) = self.require(&[State::Instantiated], "fmi2EnterInitializationMode") {
            return s;
        }
        match self.model.initialize(self.start_time) {
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
                Status::Ok
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
        let now = self.model.time();
        if h.is_nan() || h <= 0.0 || !h.is_finite() || !t.is_finite() {
            return self.fail(Status::Error, format!("invalid step: t = {t}, h = {h}"));
        }
        if (t - now).abs() > 1e-9 * now.abs().max(1.0) {
            return self.fail(
                Status::Error,
                format!("fmi2DoStep at t = {t} but the instance is at t = {now}"),
            );
        }
        match self.model.do_step(h).and_then(|_| self.model.refresh()) {
            Ok(()) => Status::Ok,
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
        self.model.time()
    }

    fn get_state(&mut self) -> Result<Box<dyn std::any::Any + Send>, (Status, String)> {
        if matches!(self.state, State::Error) {
            return Err((Status::Error, "no state to get in the error state".into()));
        }
        Ok(Box::new((self.model.snapshot(), self.state)))
    }

    fn set_state(&mut self, s: &(dyn std::any::Any + Send)) -> Status {
        let Some((snap, state)) = s.downcast_ref::<(M::Snapshot, State)>() else {
            return self.fail(
                Status::Error,
                "the FMU state belongs to another model".into(),
            );
        };
        match self.model.restore(snap.clone()) {
            Ok(()) => {
                self.state = if *state == State::StepFailed {
                    State::StepComplete
                } else {
                    *state
                };
                Status::Ok
            }
            Err(e) => self.fail(Status::Error, format!("cannot restore the state: {e}")),
        }
    }

    fn serialize(&mut self, s: &(dyn std::any::Any + Send)) -> Result<Vec<u8>, (Status, String)> {
        let Some((snap, _)) = s.downcast_ref::<(M::Snapshot, State)>() else {
            return Err((
                Status::Error,
                "the FMU state belongs to another model".into(),
            ));
        };
        let body = serde_json::to_vec(snap).map_err(|e| (Status::Error, e.to_string()))?;
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
        let snap: M::Snapshot = serde_json::from_slice(body).map_err(|e| bad(&e.to_string()))?;
        Ok(Box::new((snap, State::StepComplete)))
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
