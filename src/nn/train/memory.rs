//! Allocator tuning for training.
//!
//! A training step frees and allocates the same multi-megabyte tensors
//! (edge activations are B × N² × H floats) every step. mimalloc, the
//! global allocator of our binaries and of the `learn` bench, returns freed
//! pages to the OS 1 s after they fall idle (v3's default), and a step at
//! batch 128 takes 1-7 s, so the kernel zeroes them again on the next
//! touch. perf on a running policy training put that page zeroing at 7.6 %
//! of the process's CPU time, all of it on the thread that also runs the
//! single-threaded element-wise ops, so it lengthened every step.

/// mimalloc's `mi_option_purge_delay` (`mimalloc.h`, v3): the crate does
/// not export the constant.
const MI_OPTION_PURGE_DELAY: libmimalloc_sys::mi_option_t = 15;

/// Tells mimalloc never to return freed pages to the OS in this process.
/// The resident set stays at the step's high-water mark (1-2 GB for a
/// batch of 128 at N = 19), which a training process wants anyway. Has no
/// effect when mimalloc is not the global allocator. Not for the server,
/// whose memory should shrink back after a burst.
pub fn keep_freed_pages() {
    // SAFETY: sets an integer option; mimalloc's options are atomics.
    unsafe { libmimalloc_sys::mi_option_set(MI_OPTION_PURGE_DELAY, -1) };
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pins the constant to the option: index 15 must hold the purge
    /// delay's default (1000 ms in v3's `options.c`) before we set it, and its
    /// neighbours must not (eager-commit delay 1, NUMA nodes 0).
    #[test]
    fn the_constant_names_the_purge_delay() {
        // SAFETY: reads and writes integer options.
        unsafe {
            let get = |o| libmimalloc_sys::mi_option_get(o);
            assert_eq!(get(MI_OPTION_PURGE_DELAY), 1000);
            assert_ne!(get(MI_OPTION_PURGE_DELAY - 1), 1000);
            assert_ne!(get(MI_OPTION_PURGE_DELAY + 1), 1000);
            keep_freed_pages();
            assert_eq!(get(MI_OPTION_PURGE_DELAY), -1);
            libmimalloc_sys::mi_option_set(MI_OPTION_PURGE_DELAY, 1000);
        }
    }
}
