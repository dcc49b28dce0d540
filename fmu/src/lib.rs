//! FMI 2.0 Co-Simulation C ABI for the HydroBench models.
//!
//! One shared library serves every HydroBench FMU: each FMU ships it under its own model
//! identifier, and `fmi2Instantiate` picks the model from the GUID, which is derived from
//! the model description's content. Every exported function catches panics, checks its
//! pointers and the instance's state, and answers misuse with `fmi2Error` or
//! `fmi2Discard` and a message through the host's logger.

pub mod docs;
pub mod ffi;
pub mod instance;
pub mod models;
pub mod registry;
pub mod slave;

use std::ffi::{c_char, c_void};
use std::panic::{catch_unwind, AssertUnwindSafe};

use ffi::*;
use instance::{c_str, Component, Kind, Logger};
use registry::{free_state, is_state, live, new_state, StateBox};
use slave::Value;

type Boxed = Box<dyn Component>;

/// Run `f` on the instance behind `c`, turning panics and bad pointers into errors.
fn with<F>(c: Component_, name: &str, f: F) -> Status
where
    F: FnOnce(&mut dyn Component) -> Status,
{
    let key = c as usize;
    if c.is_null() || !live().lock().map(|l| l.contains(&key)).unwrap_or(false) {
        return Status::Error;
    }
    // SAFETY: the pointer is one we handed out and have not freed (checked above).
    let comp: &mut Boxed = unsafe { &mut *(c as *mut Boxed) };
    match catch_unwind(AssertUnwindSafe(|| f(comp.as_mut()))) {
        Ok(s) => s,
        Err(_) => {
            let _ = catch_unwind(AssertUnwindSafe(|| {
                comp.logger().log(
                    Status::Fatal,
                    0,
                    &format!("{name}: internal error (panic caught)"),
                )
            }));
            Status::Fatal
        }
    }
}

#[allow(non_camel_case_types)]
type Component_ = ffi::Component;

fn report(comp: &mut dyn Component, call: &str, r: Result<(), (Status, String)>) -> Status {
    match r {
        Ok(()) => Status::Ok,
        Err((status, msg)) => {
            comp.logger().log(status, 0, &format!("{call}: {msg}"));
            status
        }
    }
}

/// Borrow `n` elements of a C array, refusing NULL when n > 0.
///
/// # Safety
/// `p` must point to `n` valid elements when not null.
unsafe fn slice<'a, T>(p: *const T, n: usize) -> Option<&'a [T]> {
    if n == 0 {
        Some(&[])
    } else if p.is_null() {
        None
    } else {
        Some(std::slice::from_raw_parts(p, n))
    }
}

/// # Safety
/// `p` must point to `n` writable elements when not null.
unsafe fn slice_mut<'a, T>(p: *mut T, n: usize) -> Option<&'a mut [T]> {
    if n == 0 {
        Some(&mut [])
    } else if p.is_null() {
        None
    } else {
        Some(std::slice::from_raw_parts_mut(p, n))
    }
}

#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

/// # Safety
/// Called by an FMI host with valid or null pointers.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: Component_,
    on: Boolean,
    n: usize,
    categories: *const FmiString,
) -> Status {
    with(c, "fmi2SetDebugLogging", |comp| {
        let Some(cats) = slice(categories, n) else {
            comp.logger()
                .error("fmi2SetDebugLogging: categories is NULL");
            return Status::Error;
        };
        let log = comp.logger();
        log.logging_on = on != 0;
        if cats.is_empty() {
            log.categories.iter_mut().for_each(|c| *c = on != 0);
            return Status::Ok;
        }
        for &cat in cats {
            let Some(name) = c_str(cat) else {
                log.error("fmi2SetDebugLogging: a category is NULL");
                return Status::Error;
            };
            match instance::LOG_CATEGORIES
                .iter()
                .position(|(n, _)| *n == name)
            {
                Some(k) => log.categories[k] = on != 0,
                None => {
                    log.error(&format!("fmi2SetDebugLogging: unknown log category {name}"));
                    return Status::Error;
                }
            }
        }
        Status::Ok
    })
}

/// # Safety
/// Called by an FMI host with valid or null pointers.
#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instance_name: FmiString,
    fmu_type: i32,
    guid: FmiString,
    resource_location: FmiString,
    functions: *const CallbackFunctions,
    _visible: Boolean,
    logging_on: Boolean,
) -> Component_ {
    let made = catch_unwind(AssertUnwindSafe(|| {
        let name = c_str(instance_name).unwrap_or("");
        let log = Logger::new(functions, name, logging_on != 0);
        if instance_name.is_null() || name.is_empty() {
            log.error("fmi2Instantiate: instanceName is NULL or empty");
            return None;
        }
        if fmu_type != FmuType::CoSimulation as i32 {
            log.error("fmi2Instantiate: only Co-Simulation is supported");
            return None;
        }
        let Some(guid) = c_str(guid) else {
            log.error("fmi2Instantiate: fmuGUID is NULL");
            return None;
        };
        let resources =
            models::resources_or_warn(c_str(resource_location), resource_location.is_null(), &log);
        match models::instantiate(guid, log, resources) {
            Ok(comp) => Some(comp),
            Err((log, msg)) => {
                log.error(&format!("fmi2Instantiate: {msg}"));
                None
            }
        }
    }));
    match made {
        Ok(Some(comp)) => {
            let p = Box::into_raw(Box::new(comp)) as *mut c_void;
            if let Ok(mut l) = live().lock() {
                l.insert(p as usize);
            }
            p
        }
        _ => std::ptr::null_mut(),
    }
}

/// # Safety
/// `c` must be null or a pointer returned by fmi2Instantiate.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: Component_) {
    let known = live()
        .lock()
        .map(|mut l| l.remove(&(c as usize)))
        .unwrap_or(false);
    if known {
        let _ = catch_unwind(AssertUnwindSafe(|| drop(Box::from_raw(c as *mut Boxed))));
    }
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetupExperiment(
    c: Component_,
    tol_defined: Boolean,
    tol: Real,
    start: Real,
    stop_defined: Boolean,
    stop: Real,
) -> Status {
    with(c, "fmi2SetupExperiment", |comp| {
        comp.setup_experiment(
            (tol_defined != 0).then_some(tol),
            start,
            (stop_defined != 0).then_some(stop),
        )
    })
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: Component_) -> Status {
    with(c, "fmi2EnterInitializationMode", |comp| {
        comp.enter_initialization()
    })
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: Component_) -> Status {
    with(c, "fmi2ExitInitializationMode", |comp| {
        comp.exit_initialization()
    })
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2Terminate(c: Component_) -> Status {
    with(c, "fmi2Terminate", |comp| comp.terminate())
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2Reset(c: Component_) -> Status {
    with(c, "fmi2Reset", |comp| comp.reset())
}

/// Shared body of the typed getters.
unsafe fn get_values<T>(
    c: Component_,
    call: &str,
    vr: *const ValueReference,
    n: usize,
    out: *mut T,
    kind: Kind,
    conv: fn(Value) -> T,
) -> Status {
    with(c, call, |comp| {
        let (Some(vrs), Some(out)) = (slice(vr, n), slice_mut(out, n)) else {
            comp.logger().error(&format!("{call}: NULL array"));
            return Status::Error;
        };
        for (r, o) in vrs.iter().zip(out.iter_mut()) {
            match comp.get(*r, kind) {
                Ok(v) => *o = conv(v),
                Err(e) => return report(comp, call, Err(e)),
            }
        }
        Status::Ok
    })
}

/// Shared body of the typed setters.
unsafe fn set_values<T: Copy>(
    c: Component_,
    call: &str,
    vr: *const ValueReference,
    n: usize,
    vals: *const T,
    conv: fn(T) -> Value,
) -> Status {
    with(c, call, |comp| {
        let (Some(vrs), Some(vals)) = (slice(vr, n), slice(vals, n)) else {
            comp.logger().error(&format!("{call}: NULL array"));
            return Status::Error;
        };
        let mut worst = Status::Ok;
        for (r, v) in vrs.iter().zip(vals) {
            let result = comp.set(*r, conv(*v));
            let s = report(comp, call, result);
            worst = worst.max(s);
            if s >= Status::Error {
                return s;
            }
        }
        worst
    })
}

/// # Safety
/// Called by an FMI host with arrays of `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(
    c: Component_,
    vr: *const ValueReference,
    n: usize,
    value: *mut Real,
) -> Status {
    get_values(c, "fmi2GetReal", vr, n, value, Kind::Real, |v| match v {
        Value::Real(x) => x,
        _ => f64::NAN,
    })
}

/// # Safety
/// Called by an FMI host with arrays of `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetInteger(
    c: Component_,
    vr: *const ValueReference,
    n: usize,
    value: *mut Integer,
) -> Status {
    get_values(
        c,
        "fmi2GetInteger",
        vr,
        n,
        value,
        Kind::Integer,
        |v| match v {
            Value::Integer(x) => x,
            _ => 0,
        },
    )
}

/// # Safety
/// Called by an FMI host with arrays of `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBoolean(
    c: Component_,
    vr: *const ValueReference,
    n: usize,
    value: *mut Boolean,
) -> Status {
    get_values(
        c,
        "fmi2GetBoolean",
        vr,
        n,
        value,
        Kind::Boolean,
        |v| match v {
            Value::Boolean(b) => b as Boolean,
            _ => 0,
        },
    )
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetString(
    c: Component_,
    vr: *const ValueReference,
    n: usize,
    _value: *mut FmiString,
) -> Status {
    with(c, "fmi2GetString", |comp| {
        if n == 0 {
            return Status::Ok;
        }
        let first = slice(vr, n).and_then(|v| v.first().copied());
        comp.logger().error(&format!(
            "fmi2GetString: no String variable (value reference {first:?})"
        ));
        Status::Error
    })
}

/// # Safety
/// Called by an FMI host with arrays of `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(
    c: Component_,
    vr: *const ValueReference,
    n: usize,
    value: *const Real,
) -> Status {
    set_values(c, "fmi2SetReal", vr, n, value, Value::Real)
}

/// # Safety
/// Called by an FMI host with arrays of `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetInteger(
    c: Component_,
    vr: *const ValueReference,
    n: usize,
    value: *const Integer,
) -> Status {
    set_values(c, "fmi2SetInteger", vr, n, value, Value::Integer)
}

/// # Safety
/// Called by an FMI host with arrays of `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: Component_,
    vr: *const ValueReference,
    n: usize,
    value: *const Boolean,
) -> Status {
    set_values(c, "fmi2SetBoolean", vr, n, value, |b| {
        Value::Boolean(b != 0)
    })
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetString(
    c: Component_,
    _vr: *const ValueReference,
    n: usize,
    _value: *const FmiString,
) -> Status {
    with(c, "fmi2SetString", |comp| {
        if n == 0 {
            return Status::Ok;
        }
        comp.logger()
            .error("fmi2SetString: this FMU has no String variable");
        Status::Error
    })
}

/// # Safety
/// `state` must be null or point to an fmi2FMUstate slot.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(c: Component_, state: *mut FmuState) -> Status {
    with(c, "fmi2GetFMUstate", |comp| {
        if state.is_null() {
            comp.logger()
                .error("fmi2GetFMUstate: FMUstate pointer is NULL");
            return Status::Error;
        }
        // a slot that holds something must hold one of ours, which is then replaced
        if !(*state).is_null() && !is_state(*state) {
            comp.logger()
                .error("fmi2GetFMUstate: *FMUstate is not NULL and not a state of this FMU");
            return Status::Error;
        }
        match comp.get_state() {
            Ok(s) => {
                free_state(*state);
                *state = new_state(s);
                Status::Ok
            }
            Err(e) => report(comp, "fmi2GetFMUstate", Err(e)),
        }
    })
}

/// # Safety
/// `state` must be one obtained from fmi2GetFMUstate or fmi2DeSerializeFMUstate.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetFMUstate(c: Component_, state: FmuState) -> Status {
    with(c, "fmi2SetFMUstate", |comp| {
        if !is_state(state) {
            comp.logger()
                .error("fmi2SetFMUstate: FMUstate is NULL or not a state of this FMU");
            return Status::Error;
        }
        let s: &StateBox = &*(state as *const StateBox);
        comp.set_state(s.as_ref())
    })
}

/// # Safety
/// `state` must be null or point to a slot holding one of our states.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(c: Component_, state: *mut FmuState) -> Status {
    with(c, "fmi2FreeFMUstate", |comp| {
        if state.is_null() || (*state).is_null() {
            return Status::Ok;
        }
        if !free_state(*state) {
            comp.logger()
                .error("fmi2FreeFMUstate: not a state of this FMU (already freed?)");
            return Status::Error;
        }
        *state = std::ptr::null_mut();
        Status::Ok
    })
}

/// # Safety
/// Called by an FMI host with valid pointers.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: Component_,
    state: FmuState,
    size: *mut usize,
) -> Status {
    with(c, "fmi2SerializedFMUstateSize", |comp| {
        if !is_state(state) || size.is_null() {
            comp.logger()
                .error("fmi2SerializedFMUstateSize: NULL argument or not a state of this FMU");
            return Status::Error;
        }
        let s: &StateBox = &*(state as *const StateBox);
        match comp.serialize(s.as_ref()) {
            Ok(bytes) => {
                *size = bytes.len();
                Status::Ok
            }
            Err(e) => report(comp, "fmi2SerializedFMUstateSize", Err(e)),
        }
    })
}

/// # Safety
/// `out` must hold `size` bytes.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: Component_,
    state: FmuState,
    out: *mut Byte,
    size: usize,
) -> Status {
    with(c, "fmi2SerializeFMUstate", |comp| {
        if !is_state(state) || out.is_null() {
            comp.logger()
                .error("fmi2SerializeFMUstate: NULL argument or not a state of this FMU");
            return Status::Error;
        }
        let s: &StateBox = &*(state as *const StateBox);
        match comp.serialize(s.as_ref()) {
            Ok(bytes) if bytes.len() <= size => {
                std::ptr::copy_nonoverlapping(bytes.as_ptr(), out as *mut u8, bytes.len());
                Status::Ok
            }
            Ok(bytes) => {
                comp.logger().error(&format!(
                    "fmi2SerializeFMUstate: buffer of {size} bytes, {} needed",
                    bytes.len()
                ));
                Status::Error
            }
            Err(e) => report(comp, "fmi2SerializeFMUstate", Err(e)),
        }
    })
}

/// # Safety
/// `bytes` must hold `size` bytes; `state` must point to a slot.
#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: Component_,
    bytes: *const Byte,
    size: usize,
    state: *mut FmuState,
) -> Status {
    with(c, "fmi2DeSerializeFMUstate", |comp| {
        let (Some(data), false) = (slice(bytes as *const u8, size), state.is_null()) else {
            comp.logger()
                .error("fmi2DeSerializeFMUstate: NULL argument");
            return Status::Error;
        };
        match comp.deserialize(data) {
            Ok(s) => {
                // a slot holding one of our states gets it freed, not leaked (item 8); any
                // other content is the host's uninitialised slot, overwritten
                free_state(*state);
                *state = new_state(s);
                Status::Ok
            }
            Err(e) => report(comp, "fmi2DeSerializeFMUstate", Err(e)),
        }
    })
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
    c: Component_,
    _u: *const ValueReference,
    _nu: usize,
    _z: *const ValueReference,
    _nz: usize,
    _dv: *const Real,
    _dz: *mut Real,
) -> Status {
    with(c, "fmi2GetDirectionalDerivative", |comp| {
        comp.logger().error(
            "fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative is false)",
        );
        Status::Error
    })
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
    c: Component_,
    _vr: *const ValueReference,
    _n: usize,
    _order: *const Integer,
    _v: *const Real,
) -> Status {
    with(c, "fmi2SetRealInputDerivatives", |comp| {
        comp.logger()
            .error("fmi2SetRealInputDerivatives: canInterpolateInputs is false");
        Status::Error
    })
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
    c: Component_,
    _vr: *const ValueReference,
    _n: usize,
    _order: *const Integer,
    _v: *mut Real,
) -> Status {
    with(c, "fmi2GetRealOutputDerivatives", |comp| {
        comp.logger()
            .error("fmi2GetRealOutputDerivatives: maxOutputDerivativeOrder is 0");
        Status::Error
    })
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2DoStep(c: Component_, t: Real, h: Real, _no_prior: Boolean) -> Status {
    with(c, "fmi2DoStep", |comp| comp.do_step(t, h))
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2CancelStep(c: Component_) -> Status {
    with(c, "fmi2CancelStep", |comp| {
        comp.logger()
            .error("fmi2CancelStep: steps are synchronous, there is nothing to cancel");
        Status::Error
    })
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStatus(c: Component_, kind: i32, value: *mut i32) -> Status {
    with(c, "fmi2GetStatus", |comp| {
        if value.is_null() || kind != StatusKind::DoStepStatus as i32 {
            comp.logger()
                .error("fmi2GetStatus: only fmi2DoStepStatus is available");
            return Status::Discard;
        }
        *value = Status::Ok as i32;
        Status::Ok
    })
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealStatus(c: Component_, kind: i32, value: *mut Real) -> Status {
    with(c, "fmi2GetRealStatus", |comp| {
        if value.is_null() || kind != StatusKind::LastSuccessfulTime as i32 {
            comp.logger()
                .error("fmi2GetRealStatus: only fmi2LastSuccessfulTime is available");
            return Status::Discard;
        }
        *value = comp.time();
        Status::Ok
    })
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetIntegerStatus(
    c: Component_,
    _kind: i32,
    _value: *mut Integer,
) -> Status {
    with(c, "fmi2GetIntegerStatus", |comp| {
        comp.logger()
            .error("fmi2GetIntegerStatus: no integer status is available");
        Status::Discard
    })
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBooleanStatus(
    c: Component_,
    kind: i32,
    value: *mut Boolean,
) -> Status {
    with(c, "fmi2GetBooleanStatus", |comp| {
        if value.is_null() || kind != StatusKind::Terminated as i32 {
            comp.logger()
                .error("fmi2GetBooleanStatus: only fmi2Terminated is available");
            return Status::Discard;
        }
        *value = 0;
        Status::Ok
    })
}

/// # Safety
/// Called by an FMI host.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStringStatus(
    c: Component_,
    _kind: i32,
    _value: *mut FmiString,
) -> Status {
    with(c, "fmi2GetStringStatus", |comp| {
        comp.logger()
            .error("fmi2GetStringStatus: no string status is available");
        Status::Discard
    })
}
