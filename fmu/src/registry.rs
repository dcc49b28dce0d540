//! The library's registries of live instances and FMU states, and what frees them when
//! the host unloads the library. A pointer the host passes in is used only when it is in
//! one of them: a stale or foreign one is refused instead of dereferenced.

use std::collections::BTreeSet;
use std::panic::catch_unwind;
use std::sync::Mutex;

use crate::ffi::FmuState;

/// A state as handed to the host: the instance's snapshot, type-erased.
pub type StateBox = Box<dyn std::any::Any + Send>;

/// Live instances, so a stale or foreign pointer is refused instead of dereferenced.
/// A plain static (not a lazily built one) so that unloading the library frees it.
static LIVE: Mutex<BTreeSet<usize>> = Mutex::new(BTreeSet::new());

/// Live FMU states, for the same reason: fmi2SetFMUstate and the others refuse a pointer
/// that is not one of ours instead of dereferencing it (issue 16, item 8).
static STATES: Mutex<BTreeSet<usize>> = Mutex::new(BTreeSet::new());

pub fn live() -> &'static Mutex<BTreeSet<usize>> {
    &LIVE
}

pub fn is_state(p: FmuState) -> bool {
    !p.is_null()
        && STATES
            .lock()
            .map(|s| s.contains(&(p as usize)))
            .unwrap_or(false)
}

/// Hand a new state to the host, registered.
pub fn new_state(s: StateBox) -> FmuState {
    let p = Box::into_raw(Box::new(s)) as FmuState;
    if let Ok(mut set) = STATES.lock() {
        set.insert(p as usize);
    }
    p
}

/// Free a state of ours; false (and nothing done) for any other pointer.
///
/// # Safety
/// A registered pointer is one `new_state` made and nobody freed.
pub unsafe fn free_state(p: FmuState) -> bool {
    let known = !p.is_null()
        && STATES
            .lock()
            .map(|mut s| s.remove(&(p as usize)))
            .unwrap_or(false);
    if known {
        drop(Box::from_raw(p as *mut StateBox));
    }
    known
}

/// Runs when the host unloads the library (dlclose): frees the registries and the model
/// descriptions cached for GUID lookup, which otherwise stay behind at every reload
/// (issue 16, item 4: 255 kB per reload). Instances and states the host did not free are
/// left alone: their memory is the host's to leak. An ELF `.fini_array` entry is the
/// loader's own unload hook; no crate is needed for one function pointer.
extern "C" fn unload() {
    let _ = catch_unwind(|| {
        if let Ok(mut l) = LIVE.lock() {
            std::mem::take(&mut *l);
        }
        if let Ok(mut s) = STATES.lock() {
            std::mem::take(&mut *s);
        }
        crate::models::forget_guids();
    });
}

#[cfg(target_os = "linux")]
#[used]
#[link_section = ".fini_array"]
static UNLOAD: extern "C" fn() = unload;
