//! A hint to bring memory into the cache ahead of a streaming read.
//!
//! The passes over a level read columns that were last touched long before (the first pass
//! reads the whole record before the moment pass starts), so they come from memory. Where
//! a loop consumes a column slower than the processor's own prefetching expects, or in
//! pieces too short for it to lock on, asking for the line a few hundred samples ahead
//! keeps the loop from waiting on memory.

/// Samples ahead of the one being read that a streaming loop asks for.
pub(crate) const AHEAD: usize = 256;

/// Ask for the cache line `AHEAD` samples past `column[at]` (a hint: it reads nothing into
/// the program and never faults, past the column's end either; nothing on processors
/// without the instruction).
#[inline(always)]
pub(crate) fn ahead(column: &[f64], at: usize) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch only hints: it reads nothing and never faults, whatever the
    // address (`wrapping_add` keeps the pointer arithmetic itself defined).
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>(column.as_ptr().wrapping_add(at + AHEAD).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (column, at);
}
