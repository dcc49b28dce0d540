//! Independent runs on all cores: a work queue over scoped threads, results in the
//! order of the inputs, one progress bar.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use indicatif::{ProgressBar, ProgressStyle};

/// A progress bar over `len` items with `what` in its template (hidden when `shown` is
/// false, e.g. inside tests and studies).
pub fn bar(len: usize, what: &str, shown: bool) -> ProgressBar {
    if !shown {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len as u64);
    if let Ok(style) = ProgressStyle::with_template(&format!(
        "{what} {{bar:30}} {{pos}}/{{len}} {{elapsed}} {{msg}}"
    )) {
        bar.set_style(style);
    }
    bar
}

/// `f` over `items` on all cores; `label` names an item on the bar as it finishes.
pub fn map<T: Sync, R: Send>(
    items: &[T],
    bar: &ProgressBar,
    label: impl Fn(&T) -> String + Sync,
    f: impl Fn(&T) -> R + Sync,
) -> Vec<R> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let next = AtomicUsize::new(0);
    let slots: Mutex<Vec<Option<R>>> = Mutex::new((0..items.len()).map(|_| None).collect());
    std::thread::scope(|scope| {
        for _ in 0..cores.min(items.len()) {
            scope.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                let Some(item) = items.get(k) else { break };
                let r = f(item);
                bar.set_message(label(item));
                bar.inc(1);
                slots.lock().expect("no panic while holding the lock")[k] = Some(r);
            });
        }
    });
    bar.finish_and_clear();
    slots
        .into_inner()
        .expect("threads joined")
        .into_iter()
        .map(|r| r.expect("every item was taken"))
        .collect()
}
