//! Co-simulation stepping and status (FMI 2.0 sections 4.2.2-4.2.3), and the derivative
//! calls this FMU declares it does not provide (section 2.1.9).

use crate::ffi::*;
use crate::{with, Component_};

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
