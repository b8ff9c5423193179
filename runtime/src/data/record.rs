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
        if !(record.ts.is_finite() && record.ts > 0.0) {
            return Err(DataError::BadSampleInterval { ts: record.ts });
        }
        let mut col_of = vec![None; ir.signals.len()];
        for s in ir.measured_signals() {
            let name = &ir.signal(s).name;
            match record.names.iter().position(|n| n == name) {
                Some(k) => col_of[s.index()] = Some(k),
                None => {
                    return Err(DataError::MissingColumn {
                        path: origin,
                        signal: name.clone(),
                        present: record.names.join(", "),
                    })
                }
            }
        }
        let n = record.len();
        for (name, col) in record.names.iter().zip(&record.columns) {
            if col.len() != n {
                return Err(DataError::RaggedRecord {
                    path: origin,
                    column: name.clone(),
                    expected: n,
                    found: col.len(),
                });
            }
        }
        for k in col_of.iter().flatten() {
            if let Some(i) = record.columns[*k].iter().position(|v| !v.is_finite()) {
                return Err(DataError::NonFinite {
                    path: origin,
                    line: i as u64 + 1,
                    column: record.names[*k].clone(),
                    value: record.columns[*k][i],
                });
            }
        }
        if n < MIN_SAMPLES {
            return Err(DataError::TooFewSamples {
                path: origin,
                n,
                need: MIN_SAMPLES,
            });
        }
        Ok(RecordSource {
            origin,
            record,
            col_of,
        })
    }
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
