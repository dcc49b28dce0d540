//! FMI 2.0 Co-Simulation C ABI for the HydroBench models.
//!
//! One shared library serves every HydroBench FMU: each FMU ships it under its own model
//! identifier, and `fmi2Instantiate` picks the model from the GUID, which is derived from
//! the model description's content. Every exported function catches panics, checks its
//! pointers and the instance's state, and answers misuse with `fmi2Error` or
//! `fmi2Discard` and a message through the host's logger.

pub mod docs;
pub mod ffi;
mod fmu_state;
pub mod instance;
pub mod models;
pub mod registry;
pub mod slave;
mod step;
mod values;

// The exported functions, grouped by the standard's sections; this file holds the
// instance's life cycle and what every call shares.
pub use fmu_state::*;
pub use step::*;
pub use values::*;

use std::ffi::{c_char, c_void};
use std::panic::{catch_unwind, AssertUnwindSafe};

use ffi::*;
use instance::{c_str, Component, Logger};
use registry::live;

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
        Ok(None) => std::ptr::null_mut(),
        Err(_) => {
            // the closure's logger went down with the panic: a fresh one, from the same
            // host arguments, tells the host why it gets NULL (errors are always logged)
            let _ = catch_unwind(AssertUnwindSafe(|| {
                let name = c_str(instance_name).unwrap_or("");
                Logger::new(functions, name, logging_on != 0)
                    .error("fmi2Instantiate: internal error (panic caught)");
            }));
            std::ptr::null_mut()
        }
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
