//! candle's CPU thread count, fixed once per process.
//!
//! candle reads its thread count on every matrix product (and the barrier pool of its
//! element-wise kernels on first use) from `RAYON_NUM_THREADS`; when that is unset, its
//! fallback counts physical cores by reading and parsing `/proc/cpuinfo`, on every call. On
//! the 2-core machine that was most of the shipped forecaster's inference time at batch 1
//! (2.7 ms against 0.8 ms with the variable set; docs/PERFORMANCE.md). Setting the variable
//! once at start-up turns the count into an environment lookup.

/// Set `RAYON_NUM_THREADS` to the parallelism available to this process (CPU affinity and
/// cgroup quota respected) unless it is already set; returns the count in force.
///
/// Call it first thing in `main`, before any other thread starts: the environment is
/// process-wide.
pub fn fix_candle_thread_count() -> usize {
    if let Some(n) = std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .filter(|&n| n > 0)
    {
        return n;
    }
    let n = std::thread::available_parallelism().map_or(1, |n| n.get());
    std::env::set_var("RAYON_NUM_THREADS", n.to_string());
    n
}
