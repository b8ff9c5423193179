//! The property the `csv` and `binary` fuzz targets (`fuzz/fuzz_targets/`) and their smoke
//! tests check: for any bytes, the readers return data or an error — never a panic — and
//! data they return is complete and finite. The `numerics` target's property, which runs
//! identification and detection, is `crate::fuzz`.

use super::*;

/// The model the `csv` and `binary` fuzz targets (and their deterministic miniatures in the
/// tests) read their inputs as: one body, measured position and input.
pub const FUZZ_MODEL: &str = "model m {
    body m = 1.0
    input u on m
    measure m.x, u
    spring k (ground, m) ~ 4.0
    damper d (ground, m) ~ 0.4
}";

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
            check_streamed(&src, ir);
        }
        if let Ok(rec) = read_record_bytes(path, bytes, opts) {
            check_record(&rec);
        }
    }
}

/// A level that opened streams complete, finite chunks of its measured signals and, if the
/// stream succeeds, at least [`MIN_SAMPLES`] samples at a positive sample interval.
fn check_streamed(src: &dyn LevelSource, ir: &ModelIr) {
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

/// A record read whole: at least two samples, every column as long, finite values, a
/// positive sample interval.
fn check_record(rec: &Record) {
    let n = rec.len();
    // (A file of time stamps alone is a record without columns.)
    assert!(n >= 2 || rec.columns.is_empty(), "a record of {n} samples");
    assert!(rec.columns.iter().all(|c| c.len() == n), "ragged record");
    assert!(rec.columns.iter().flatten().all(|v| v.is_finite()));
    assert!(rec.ts.is_finite() && rec.ts > 0.0);
}

/// The property of the `binary` fuzz target: the file at `path` (any bytes; the target
/// writes them there, since the MAT, HDF5 and Parquet readers read files) opened as a
/// level of `ir` in the format its content tells, streamed, and read whole as a record —
/// with the signals' own names and with MATLAB's (`m_x` for `m.x`, through the
/// renaming of `--map`). Data or an error, never a panic; data returned is complete,
/// finite and long enough. Panics only if a reader breaks its contract.
pub fn check_data_file(path: &Path, ir: &ModelIr) {
    let matlab: Vec<(String, String)> = ir
        .signals
        .iter()
        .filter(|s| s.measured && s.name.contains('.'))
        .map(|s| (s.name.replace('.', "_"), s.name.clone()))
        .collect();
    let opts = [
        CsvOptions::default(),
        CsvOptions {
            map: matlab,
            ..Default::default()
        },
    ];
    for opts in &opts {
        if let Ok(src) = FileSource::open(path, ir, opts) {
            check_streamed(&src, ir);
        }
        if let Ok(rec) = read_record_within(path, opts, false) {
            check_record(&rec);
        }
    }
}
