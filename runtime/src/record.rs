//! An in-memory, uniformly sampled multi-signal record (one excitation level).

/// Columns of equal length sampled every `ts` seconds starting at `t0`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Record {
    /// Signal names (`m1.x`, `m1.v`, `u`, …), one per column; never contains `t`.
    pub names: Vec<String>,
    pub columns: Vec<Vec<f64>>,
    pub ts: f64,
    pub t0: f64,
}

impl Record {
    pub fn len(&self) -> usize {
        self.columns.first().map_or(0, Vec::len)
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.names
            .iter()
            .position(|n| n == name)
            .map(|i| self.columns[i].as_slice())
    }
}
