//! The host's logger: the callback through which an instance reports, filtered by the
//! log categories of `ffi::LOG_CATEGORIES`.

use std::ffi::CString;

use crate::ffi::{CallbackFunctions, CallbackLogger, ComponentEnvironment, Status, LOG_CATEGORIES};

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

    /// A warning the host always sees, logging on or off: kept for what a user must not
    /// miss, such as a parameter file that is not read.
    pub fn warn(&self, message: &str) {
        let Some(cb) = self.callback else { return };
        let cat = CString::new(LOG_CATEGORIES[1].0).unwrap_or_default();
        let msg = CString::new(message.replace('\0', " ")).unwrap_or_default();
        // SAFETY: as in `log`
        unsafe {
            cb(
                self.environment,
                self.instance_name.as_ptr(),
                Status::Warning,
                cat.as_ptr(),
                c"%s".as_ptr(),
                msg.as_ptr(),
            )
        };
    }
}
