//! In-memory records bound to a model.

use super::*;

/// An in-memory record bound to a model (checked once on construction).
#[derive(Clone, Debug)]
pub struct RecordSource<'r> {
    origin: String,
    record: &'r Record,
    col_of: Vec<Option<usize>>,
}

impl<'r> RecordSource<'r> {
    pub fn new(
        record: &'r Record,
        ir: &ModelIr,
        origin: impl Into<String>,
    ) -> Result<Self, DataError> {
        let origin = origin.into();
        let columns: Vec<&[f64]> = record.columns.iter().map(Vec::as_slice).collect();
        let col_of = check_columns(ir, &origin, &record.names, &columns, record.ts)?;
        Ok(RecordSource {
            origin,
            record,
            col_of,
        })
    }
}

/// The checks of a level held in memory (a [`Record`], or the arrays of the Python
/// package): every measured signal of `ir` has a column in `names`, all `columns` are of
/// one length, the measured ones finite, there are enough samples, and the sample interval
/// `ts` is a positive number. Returns, by signal index, where in `columns` each measured
/// signal is. `origin` names the level in the errors.
pub fn check_columns(
    ir: &ModelIr,
    origin: &str,
    names: &[String],
    columns: &[&[f64]],
    ts: f64,
) -> Result<Vec<Option<usize>>, DataError> {
    let n = columns.first().map_or(0, |c| c.len());
    for (name, col) in names.iter().zip(columns) {
        if col.len() != n {
            return Err(DataError::RaggedRecord {
                path: origin.to_string(),
                column: name.clone(),
                expected: n,
                found: col.len(),
            });
        }
    }
    let mut col_of = vec![None; ir.signals.len()];
    for s in ir.measured_signals() {
        let name = &ir.signal(s).name;
        match names.iter().position(|n| n == name) {
            Some(k) => col_of[s.index()] = Some(k),
            None => {
                return Err(DataError::MissingColumn {
                    path: origin.to_string(),
                    signal: name.clone(),
                    present: names.join(", "),
                })
            }
        }
    }
    for k in col_of.iter().flatten() {
        if let Some(i) = columns[*k].iter().position(|v| !v.is_finite()) {
            return Err(DataError::SampleNonFinite {
                path: origin.to_string(),
                sample: i as u64 + 1,
                column: names[*k].clone(),
                value: columns[*k][i],
            });
        }
    }
    if n < MIN_SAMPLES {
        return Err(DataError::TooFewSamples {
            path: origin.to_string(),
            n,
            need: MIN_SAMPLES,
        });
    }
    if !(ts.is_finite() && ts > 0.0) {
        return Err(DataError::BadSampleInterval { ts });
    }
    Ok(col_of)
}

impl LevelSource for RecordSource<'_> {
    fn origin(&self) -> String {
        self.origin.clone()
    }
    fn ts(&self) -> f64 {
        self.record.ts
    }
    fn stream(
        &self,
        max_len: usize,
        sink: &mut dyn FnMut(&[&[f64]], usize),
    ) -> Result<(), DataError> {
        let n = self.record.len();
        let mut start = 0;
        let mut cols: Vec<&[f64]> = vec![&[]; self.col_of.len()];
        while start < n {
            let len = max_len.max(1).min(n - start); // progress even for `max_len` 0
            for (s, c) in self.col_of.iter().enumerate() {
                cols[s] = match c {
                    Some(k) => &self.record.columns[*k][start..start + len],
                    None => &[],
                };
            }
            sink(&cols, len);
            start += len;
        }
        Ok(())
    }
}
