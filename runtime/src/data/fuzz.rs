//! The property the CSV fuzz target (`fuzz/fuzz_targets/csv.rs`) and its smoke test check:
//! for any bytes, the readers return data or an error — never a panic — and data they
//! return is complete and finite.

use super::*;

/// Open and stream `bytes` as a level of `ir` and read them as a record, from memory
/// through the same parser as a file (`path` only names them). Panics only if a reader
/// breaks its contract.
pub fn check_csv_bytes(path: &Path, bytes: &[u8], ir: &ModelIr) {
    let opts = [
        CsvOptions::default(),
        CsvOptions {
            ts: Some(0.01),
            ..Default::default()
        },
    ];
    for opts in &opts {
        if let Ok(src) = CsvSource::from_bytes(path, bytes, ir, opts) {
            let mut n = 0;
            let streamed = src.stream(97, &mut |cols, len| {
                for s in ir.measured_signals() {
                    let c = &cols[s.index()];
                    assert!(c.len() >= len, "a chunk shorter than its length");
                    assert!(c[..len].iter().all(|v| v.is_finite()), "a non-finite value");
                }
                n += len;
            });
            if streamed.is_ok() {
                assert!(n >= MIN_SAMPLES, "{n} samples streamed");
                assert!(src.ts().is_finite() && src.ts() > 0.0);
            }
        }
        if let Ok(rec) = read_record_bytes(path, bytes, opts) {
            let n = rec.len();
            assert!(rec.columns.iter().all(|c| c.len() == n), "ragged record");
            assert!(rec.columns.iter().flatten().all(|v| v.is_finite()));
            assert!(rec.ts.is_finite() && rec.ts > 0.0);
        }
    }
}
