//! The deployed process's resident memory: large buffers that frames touch only in part stay
//! unbacked where they are not touched.
//!
//! The estimator reserves its buffers for the largest frame and commits pages only as far as
//! frames use them (a region match touches the rows it matches; a cloud fills as many points
//! as it has). That holds while each large buffer has pages of its own from the kernel.
//! glibc's malloc maps an allocation of 128 KiB or more on its own, but it raises that
//! threshold to the size of the first such block freed (up to 32 MiB): after start-up has
//! freed one (a model file's bytes, a background), later blocks come from the heap. A block
//! used and freed there stays committed, and a buffer placed in it later holds those pages
//! (and `calloc` clears them again) however little of it frames touch. On the
//! service's dataset this was 21 MB of its peak resident memory (109 → 88 MB; `python3
//! scripts/serve_latency.py` beside `camplace serve`, as in docs/design/serving.md).

/// Allocations from this size up are mapped on their own, and unmapped when freed.
const OWN_PAGES_FROM: usize = 128 * 1024;

/// Fixes the C library's threshold for mapping an allocation on its own at 128 KiB, so it no
/// longer follows the largest block freed. Call it first thing in a long-running deployed
/// process (`camplace run`, `camplace serve`): it applies to what is allocated after it. Per
/// frame nothing is allocated, so frame times do not change. Without glibc it does nothing
/// (musl always maps large blocks on their own).
pub fn keep_large_buffers_unbacked() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets allocator parameters; both values are in range (glibc takes
    // any threshold up to 32 MiB), and a refusal (return 0) leaves the defaults in force.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, OWN_PAGES_FROM as libc::c_int);
        // Above it, the top of the heap is given back once this much of it is free.
        libc::mallopt(libc::M_TRIM_THRESHOLD, OWN_PAGES_FROM as libc::c_int);
    }
}

#[cfg(all(test, target_os = "linux", target_env = "gnu"))]
mod tests {
    use super::*;

    /// This process's resident anonymous memory in kB (`RssAnon` in /proc/self/status).
    fn resident_anon_kb() -> u64 {
        let status = std::fs::read_to_string("/proc/self/status").unwrap();
        let line = status.lines().find(|l| l.starts_with("RssAnon:")).unwrap();
        line.split_whitespace().nth(1).unwrap().parse().unwrap()
    }

    #[test]
    fn a_buffer_freed_at_start_up_leaves_no_committed_pages_behind() {
        keep_large_buffers_unbacked();
        // A large block freed: glibc's adaptive threshold would now rise to its size.
        drop(std::hint::black_box(vec![1u8; 30 << 20]));
        let before = resident_anon_kb();
        // Start-up's transient buffer (a file's bytes), used and freed: below the risen
        // threshold it would stay in the heap, committed.
        drop(std::hint::black_box(vec![1u8; 24 << 20]));
        // A buffer reserved for the largest frame, untouched yet: in that heap block it
        // would be cleared, and so committed, page by page.
        let buffer = std::hint::black_box(vec![0u8; 24 << 20]);
        let grown_kb = resident_anon_kb().saturating_sub(before);
        // Other tests running beside this one may commit a few MB of their own meanwhile.
        assert!(grown_kb < 12 << 10, "24 MiB freed and 24 MiB reserved left {grown_kb} kB committed");
        drop(buffer);
    }
}
