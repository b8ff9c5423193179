//! The arrow (the first 40 000 samples, input amplitude growing linearly in time) cut into
//! levels of growing amplitude, each identified alone: the per-level fits show a hardening
//! spring as an equivalent linear stiffness that rises with the level.

use super::data::{record_upsampled, Segment, SilverboxData, ARROW_LEN};
use super::error::SilverboxError;
use crate::data::{LevelSource, RecordSource};
use crate::describe::std_dev;
use crate::ident::IdentifyOptions;
use crate::record::Record;
use dynid_ir::ir::ModelIr;
use serde::Serialize;

/// One excitation level cut from the arrow, with the per-level linear fit.
#[derive(Clone, Debug, Serialize)]
pub struct ArrowLevel {
    pub segment: Segment,
    /// Standard deviations of input and output over the segment, mV.
    pub u_std_mv: f64,
    pub y_std_mv: f64,
    /// Per-level identification of the (linear) model.
    pub params: Vec<crate::ident::ParamEstimate>,
}

/// Cut the arrow into `n` consecutive equal segments: excitation levels of growing
/// amplitude (the arrow's input amplitude grows linearly with time).
pub fn arrow_levels(n: usize) -> Vec<Segment> {
    (0..n)
        .map(|i| Segment {
            start: i * ARROW_LEN / n,
            end: (i + 1) * ARROW_LEN / n,
        })
        .collect()
}

fn std_mv(x: &[f64]) -> f64 {
    1e3 * std_dev(x)
}

/// Records of the arrow levels (band-limited interpolated by `upsample_factor`, see
/// [`record_upsampled`]) and the per-level identification of `ir` (for detection: the
/// equivalent linear stiffness of a hardening spring rises with the level).
pub fn arrow_level_fits(
    ir: &ModelIr,
    data: &SilverboxData,
    n: usize,
    opts: &IdentifyOptions,
    upsample_factor: usize,
) -> Result<(Vec<Record>, Vec<ArrowLevel>), SilverboxError> {
    let segs = arrow_levels(n);
    let records = segs
        .iter()
        .map(|s| record_upsampled(ir, data, *s, upsample_factor))
        .collect::<Result<Vec<_>, _>>()?;
    let sources = records
        .iter()
        .zip(&segs)
        .map(|(r, s)| RecordSource::new(r, ir, format!("arrow[{}..{}]", s.start, s.end)))
        .collect::<Result<Vec<_>, _>>()?;
    let levels: Vec<&dyn LevelSource> = sources.iter().map(|s| s as &dyn LevelSource).collect();
    let fits = crate::ident::identify_per_level(ir, &levels, opts)?;
    let out = segs
        .iter()
        .zip(fits)
        .map(|(s, f)| ArrowLevel {
            segment: *s,
            u_std_mv: std_mv(&data.u[s.start..s.end]),
            y_std_mv: std_mv(&data.y[s.start..s.end]),
            params: f.params,
        })
        .collect();
    Ok((records, out))
}
