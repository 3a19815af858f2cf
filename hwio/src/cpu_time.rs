//! CPU time, for sizing a cell PC: the process's CPU clock over each frame's estimation
//! (the estimator thread and the worker threads its stereo stages use) and over a whole
//! run. Wall-clock latency says whether a frame is in time; CPU time says how much of the
//! machine it took, and so how many cores a given frame rate needs.

use std::time::Duration;

/// CPU time used so far by the calling thread.
#[cfg(test)]
fn thread_cpu_time() -> Duration {
    clock(libc::CLOCK_THREAD_CPUTIME_ID)
}

/// CPU time used so far by every thread of this process.
pub fn process_cpu_time() -> Duration {
    clock(libc::CLOCK_PROCESS_CPUTIME_ID)
}

fn clock(id: libc::clockid_t) -> Duration {
    let mut t = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `t` is a valid, writable timespec for the call's duration, and both clock ids
    // used here exist on every Linux since 2.6.12; on failure `t` stays zero.
    let rc = unsafe { libc::clock_gettime(id, &mut t) };
    if rc != 0 {
        return Duration::ZERO;
    }
    Duration::new(u64::try_from(t.tv_sec).unwrap_or(0), u32::try_from(t.tv_nsec).unwrap_or(0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Instant;

    /// Spins for `d` of wall time.
    fn spin(d: Duration) -> u64 {
        let start = Instant::now();
        let mut x = 0u64;
        while start.elapsed() < d {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        }
        x
    }

    #[test]
    fn a_thread_that_works_uses_cpu_time_and_a_sleeping_one_does_not() {
        let before = thread_cpu_time();
        std::hint::black_box(spin(Duration::from_millis(30)));
        let worked = thread_cpu_time() - before;
        // A thread cannot use more CPU than the wall time it ran; it may be descheduled.
        let wall = Duration::from_millis(30);
        assert!(worked > Duration::ZERO, "{worked:?}");
        assert!(worked <= wall + Duration::from_millis(25), "{worked:?} for {wall:?} of spinning");

        let before = thread_cpu_time();
        std::thread::sleep(Duration::from_millis(30));
        let slept = thread_cpu_time() - before;
        assert!(slept < Duration::from_millis(5), "{slept:?} asleep");
    }

    #[test]
    fn the_process_clock_counts_every_threads_work() {
        let before = process_cpu_time();
        let spun: Duration = (0..2)
            .map(|_| {
                std::thread::spawn(|| {
                    let start = thread_cpu_time();
                    std::hint::black_box(spin(Duration::from_millis(20)));
                    thread_cpu_time() - start
                })
            })
            .collect::<Vec<_>>()
            .into_iter()
            .map(|h| h.join().unwrap())
            .sum();
        let process = process_cpu_time() - before;
        assert!(spun > Duration::ZERO);
        assert!(process >= spun, "the process clock {process:?} missed the threads' {spun:?}");
    }
}
