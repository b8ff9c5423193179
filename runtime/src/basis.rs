//! The plug-in point for evaluating the static basis columns of a model.

/// Evaluates the static basis expressions `ir.eval_roots()` of a model over blocks of samples.
///
/// For a block of `len` samples, root `r` evaluated at sample `n` is written to
/// `out[r * len + n]` (root-major). `signals[s]` is the column of signal `s`
/// (indexed by `SignalId`), at least `len` long for every signal the roots read; columns of
/// signals the roots do not read may be empty. `scratch` is caller-owned working memory that
/// is reused across calls, so an implementation allocates nothing once it has grown.
///
/// Implemented by the interpreter ([`crate::tape::Tape`]) and by macro-generated code; both
/// must produce bit-identical output so that the assembled least-squares matrix is identical.
pub trait BasisEval: Sync {
    /// Number of roots (static basis columns) written per sample.
    fn n_roots(&self) -> usize;
    /// Evaluate all roots over one block.
    fn eval_block(&self, signals: &[&[f64]], len: usize, out: &mut [f64], scratch: &mut Vec<f64>);
}
