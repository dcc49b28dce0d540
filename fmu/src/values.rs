//! Getting and setting variable values (FMI 2.0 section 2.1.7): the typed getters and
//! setters, checked against each model's variable list.

use crate::ffi::*;
use crate::instance::Kind;
use crate::slave::Value;
use crate::{report, slice, slice_mut, with, Component_};

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
