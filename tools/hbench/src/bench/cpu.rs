//! CPU time of the calling thread, the clock `hbench bench` reports, and of the whole
//! process, which `hbench gap` reports beside its wall time.
//!
//! Wall time counts whatever else the machine runs; the thread's CPU time
//! (`CLOCK_THREAD_CPUTIME_ID`, nanosecond resolution on Linux) counts only our work, and
//! is fine enough to time one 1 ms communication step.

/// CPU seconds the whole process (every thread) has used so far.
pub fn process_seconds() -> f64 {
    clock(libc::CLOCK_PROCESS_CPUTIME_ID)
}

/// CPU seconds the calling thread has used so far.
pub fn thread_seconds() -> f64 {
    clock(libc::CLOCK_THREAD_CPUTIME_ID)
}

fn clock(id: libc::clockid_t) -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; the clock id is a constant Linux and
    // the BSDs define. A failure leaves ts at zero, which the caller sees as no time.
    unsafe {
        libc::clock_gettime(id, &mut ts);
    }
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_clock_advances_with_work_and_not_with_sleep() {
        let t0 = thread_seconds();
        std::thread::sleep(std::time::Duration::from_millis(50));
        let slept = thread_seconds() - t0;
        let t1 = thread_seconds();
        let mut acc = 0.0f64;
        for i in 0..5_000_000u64 {
            acc += (i as f64).sqrt();
        }
        std::hint::black_box(acc);
        let worked = thread_seconds() - t1;
        assert!(slept < 0.02, "sleeping used {slept} s of CPU");
        assert!(worked > 0.0005, "work used only {worked} s of CPU");
    }
}
