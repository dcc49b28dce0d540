//! The C types of the FMI 2.0 API (fmi2TypesPlatform.h, fmi2FunctionTypes.h).

use std::ffi::{c_char, c_void};

pub type Component = *mut c_void;
pub type ComponentEnvironment = *mut c_void;
pub type FmuState = *mut c_void;
pub type ValueReference = u32;
pub type Real = f64;
pub type Integer = i32;
/// fmi2Boolean is an int; fmi2True = 1, fmi2False = 0.
pub type Boolean = i32;
pub type FmiString = *const c_char;
pub type Byte = c_char;

#[repr(i32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Status {
    Ok = 0,
    Warning = 1,
    Discard = 2,
    Error = 3,
    Fatal = 4,
    Pending = 5,
}

#[repr(i32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FmuType {
    ModelExchange = 0,
    CoSimulation = 1,
}

#[repr(i32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StatusKind {
    DoStepStatus = 0,
    PendingStatus = 1,
    LastSuccessfulTime = 2,
    Terminated = 3,
}

/// The host's logger: printf-like, so the message is always passed through "%s".
pub type CallbackLogger = Option<
    unsafe extern "C" fn(ComponentEnvironment, FmiString, Status, FmiString, FmiString, ...),
>;
pub type CallbackAllocateMemory = Option<unsafe extern "C" fn(usize, usize) -> *mut c_void>;
pub type CallbackFreeMemory = Option<unsafe extern "C" fn(*mut c_void)>;
pub type StepFinished = Option<unsafe extern "C" fn(ComponentEnvironment, Status)>;

#[repr(C)]
pub struct CallbackFunctions {
    pub logger: CallbackLogger,
    pub allocate_memory: CallbackAllocateMemory,
    pub free_memory: CallbackFreeMemory,
    pub step_finished: StepFinished,
    pub component_environment: ComponentEnvironment,
}

/// Log categories declared in every model description and used by the instances'
/// logger: declared here, where both the description (`slave`) and the logger
/// (`instance`) can read them without importing each other.
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
