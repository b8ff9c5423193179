//! Bodies measured only by their acceleration: the data has no column for their position
//! or velocity, yet a static root of the model may read them (a spring's `m2.x − m1.x`).
//! Those terms are formed from the acceleration by band-pass instruments
//! ([`super::plan::BasisMoment::D0Acc`], [`super::plan::BasisMoment::D1Acc`]), never from
//! the roots; the roots are still evaluated for every sample (the evaluator computes all
//! of them), so [`ZeroFill`] streams zeros in place of the missing columns. Signals that a
//! nonlinear term reads are then filled with their integrals of the acceleration
//! ([`super::integrate::IntegratedMotion`]), which stream over the zeros.

use crate::data::{DataError, LevelSource};

/// A level whose columns `slots` (by `SignalId`) are streamed as zeros.
pub(crate) struct ZeroFill<'a> {
    inner: &'a dyn LevelSource,
    slots: Vec<usize>,
}

impl<'a> ZeroFill<'a> {
    pub fn new(inner: &'a dyn LevelSource, slots: Vec<usize>) -> Self {
        ZeroFill { inner, slots }
    }
}

impl LevelSource for ZeroFill<'_> {
    fn origin(&self) -> String {
        self.inner.origin()
    }
    fn ts(&self) -> f64 {
        self.inner.ts()
    }
    fn locate(&self, k: usize) -> String {
        self.inner.locate(k)
    }
    fn stream(
        &self,
        max_len: usize,
        sink: &mut dyn FnMut(&[&[f64]], usize),
    ) -> Result<(), DataError> {
        // One buffer of zeros for the whole stream (chunks are at most `max_len` long).
        let zeros = vec![0.0; max_len];
        self.inner.stream(max_len, &mut |inner, len| {
            // One small vector of slices per chunk, none per sample.
            let mut cols: Vec<&[f64]> = inner.to_vec();
            for &s in &self.slots {
                if s < cols.len() {
                    cols[s] = &zeros[..len.min(zeros.len())];
                }
            }
            sink(&cols, len);
        })
    }
}
