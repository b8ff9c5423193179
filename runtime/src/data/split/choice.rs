//! The front ends' choice of how one record is cut into levels (`--segments`, `--split-by`,
//! `--cut`; Python `segments=`, `split_by=`, `cut=`): at the cycles of a repeated
//! trajectory (`super::cycles`) or by amplitude ([`super::split_record`]).

use super::cycles::{cut_cycles, Cycles, MIN_CORRELATION};
use super::error::SplitError;
use super::{default_response, split_record, Split, SplitOptions};
use crate::record::Record;
use dynid_ir::ir::{ModelIr, SignalKind};
use dynid_ir::num::sig;

/// Where one record is cut into levels (`--cut`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CutAt {
    /// At the cycles of a repeated trajectory when the record repeats with one amplitude,
    /// else by amplitude.
    #[default]
    Auto,
    /// At the cycles of a repeated trajectory (refused when the record does not repeat).
    Cycles,
    /// By the local amplitude of the response.
    Amplitude,
}

impl CutAt {
    /// The spellings of the command line and of Python: `auto`, `cycles`, `amplitude`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "auto" => Some(Self::Auto),
            "cycles" => Some(Self::Cycles),
            "amplitude" => Some(Self::Amplitude),
            _ => None,
        }
    }
}

/// How one record is cut into levels: the choices of `--segments`, `--split-by` and
/// `--cut` (Python: `segments=`, `split_by=`, `cut=`), shared by every front end so that
/// the same record gives the same levels and the same errors.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SplitChoice {
    /// Number of segments; `None`: one per cycle of a repeated trajectory, else 3 by
    /// amplitude.
    pub segments: Option<usize>,
    /// The signal whose amplitude is judged; `None`: [`default_response`].
    pub split_by: Option<String>,
    pub cut: CutAt,
}

impl SplitChoice {
    /// Whether `files` records are cut into levels: one record always is; several never,
    /// and a split option given with several is an error.
    #[allow(clippy::result_large_err)] // an error is built once, on the way out
    pub fn applies(&self, files: usize) -> Result<bool, SplitError> {
        if files <= 1 {
            return Ok(files == 1);
        }
        let flag = match (&self.segments, &self.split_by, self.cut) {
            (Some(_), _, _) => "--segments",
            (None, Some(_), _) => "--split-by",
            (None, None, CutAt::Auto) => return Ok(false),
            (None, None, _) => "--cut",
        };
        Err(SplitError::SeveralFiles { flag, files })
    }

    /// The response whose amplitude is judged (checked before the record is read).
    #[allow(clippy::result_large_err)]
    pub fn response(&self, ir: &ModelIr, origin: &str) -> Result<String, SplitError> {
        match &self.split_by {
            Some(s) => Ok(s.clone()),
            None => default_response(ir).ok_or_else(|| SplitError::NoResponse {
                model: ir.name.clone(),
                origin: origin.into(),
            }),
        }
    }

    /// Cut `record` (all columns of one file; `origin` names it in errors) into levels:
    /// at the cycles of a repeated trajectory when [`Self::cut`] allows it and a signal
    /// repeats (in auto mode only with one amplitude over the cycles), else by amplitude
    /// ([`split_record`]).
    #[allow(clippy::result_large_err)]
    pub fn split(&self, ir: &ModelIr, record: &Record, origin: &str) -> Result<Split, SplitError> {
        if let Some(segments) = self.segments.filter(|&n| n < 2) {
            return Err(SplitError::TooFewSegments { segments });
        }
        let response = self.response(ir, origin)?;
        if let Some(split) = self.at_cycles(ir, record, origin, &response)? {
            return Ok(split);
        }
        let opts = SplitOptions {
            segments: self.segments.unwrap_or(3),
            ..Default::default()
        };
        split_record(record, origin, &response, &opts)
    }

    /// The record cut at its cycles, when [`Self::cut`] allows it and a signal repeats;
    /// `None`: cut by amplitude.
    #[allow(clippy::result_large_err)]
    fn at_cycles(
        &self,
        ir: &ModelIr,
        record: &Record,
        origin: &str,
        response: &str,
    ) -> Result<Option<Split>, SplitError> {
        if self.cut == CutAt::Amplitude {
            return Ok(None);
        }
        // A reference is the planned trajectory itself; the response follows it; an input
        // repeats with it.
        let names = |pick: fn(&SignalKind) -> bool| -> Vec<String> {
            ir.signals
                .iter()
                .filter(|s| pick(&s.kind) && s.name != response)
                .filter(|s| record.column(&s.name).is_some())
                .map(|s| s.name.clone())
                .collect()
        };
        let mut candidates = names(|k| matches!(k, SignalKind::Reference(_)));
        candidates.push(response.to_string());
        candidates.extend(names(|k| matches!(k, SignalKind::Input(_))));
        let found = candidates.iter().find_map(|c| {
            cut_cycles(record, c, response, None)
                .and_then(Result::ok)
                .map(|s| (c, s))
        });
        let Some((by, per_cycle)) = found else {
            if self.cut == CutAt::Cycles {
                return Err(SplitError::NoCycles {
                    origin: origin.into(),
                    checked: candidates.join(", "),
                    correlation: MIN_CORRELATION,
                });
            }
            return Ok(None);
        };
        if self.cut == CutAt::Auto && !Cycles::alike_amplitudes(&per_cycle) {
            return Ok(None);
        }
        match self.segments {
            None => Ok(Some(per_cycle)),
            Some(n) => match cut_cycles(record, by, response, Some(n)) {
                Some(Ok(split)) => Ok(Some(split)),
                _ => {
                    let cycles = per_cycle.cycles.as_ref();
                    Err(SplitError::FewCycles {
                        origin: origin.into(),
                        by: by.clone(),
                        period: sig(cycles.map_or(0.0, |c| c.period), 5, false),
                        count: cycles.map_or(0, |c| c.cycles),
                        segments: n,
                    })
                }
            },
        }
    }
}
