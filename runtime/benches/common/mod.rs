//! What the benches share: the tool's allocator, best-of timing and the process's peak
//! memory (Linux).
// Each bench uses a part of it.
#![allow(dead_code)]

use std::time::Instant;

mod row;
pub use row::{bench_env, print_row};

/// The allocator of the `dynid` binary (see `src/main.rs`), so that peak memory and times
/// here are those of the tool.
#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// `VmHWM` and `VmRSS` in MiB (Linux), `None` elsewhere.
pub fn memory() -> Option<(f64, f64)> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let field = |name: &str| {
        s.lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse::<f64>().ok())
            .map(|kb| kb / 1024.0)
    };
    Some((field("VmHWM:")?, field("VmRSS:")?))
}

/// Reset the high-water mark to the current resident size (Linux ≥ 4.0).
pub fn reset_peak() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

pub fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..runs {
        let t = Instant::now();
        let v = f();
        best = best.min(t.elapsed().as_secs_f64());
        last = Some(v);
    }
    (best, last.unwrap())
}
