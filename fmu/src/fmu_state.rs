//! Saving, restoring and serialising the FMU state (FMI 2.0 section 2.1.8).

use crate::ffi::*;
use crate::registry::{free_state, is_state, new_state, StateBox};
use crate::{report, slice, with, Component_};

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
