//! Moment statistics as a value: what identification accumulates per level, with the design
//! it was made with, computed from any piece of data, merged, and solved.
//!
//! A [`MomentStats`] holds one *piece* per level of the pooled problem: the level's block
//! sums of the filter-output moments (`LevelMoments`: `Σ ι wᵀ`, `Σ s ι wᵀ` per time
//! block and the products at the block boundaries), its first-pass statistics (length,
//! sample interval, mean, spread and noise floor of every measured signal), what the
//! report says of it (its origin, rests left out, time blocks), whether its drivers are
//! centred, and the filters of its estimated velocities. The pooled least-squares problem
//! stacks the rows of its levels and its standard errors sum the levels' terms, so a merge
//! is the concatenation of the pieces: associative, and exact — merged statistics solve to
//! the identification of the same records given together, to rounding (test
//! `tests/moments.rs`).
//!
//! A piece is a record: a boundary between pieces starts a new level, with the filters
//! started afresh and boundary terms of its own, as two files would be. Cutting a record
//! into pieces therefore gives the identification of those pieces given as separate
//! records, not that of the whole record; the cost is one filter start-up (a few time
//! constants of the slowest filter, [`super::design::min_duration`]) per cut, whose
//! samples the moments still use, and a shortest piece that must be long enough for the
//! design's filters and blocks (refused otherwise, naming the length it needs).
//!
//! Everything the in-process identification decides from all levels at once is decided
//! before the pieces are measured and carried by the [`MomentDesign`]: the corners (given,
//! from the model's `filter` block, or designed from a first pass over a sample of the
//! data), the time blocks per level (from the shortest level of that sample), whether the
//! noise corrections are attached, and the options that change the moments. Pieces are
//! only merged with the same design of the same model (the model's printed source,
//! hashed): anything else is refused ([`MomentsError`]).

mod file;

pub use file::{FORMAT_VERSION, MAGIC};

use super::filter::Hold;
use super::first_pass::LevelStats;
use super::measure::{design_levels, first_pass_all, measure_pieces, measurement_of};
use super::moments::LevelMoments;
use super::types::{CornerSource, Identification, IdentifyError, IdentifyOptions, LevelInfo};
use crate::data::LevelSource;
use crate::tape::Tape;
use dynid_ir::ir::{ModelIr, SignalId};
use serde::{Deserialize, Serialize};

/// One level of the pooled problem, measured: its moments and what the solve and the
/// report read of it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct LevelPiece {
    pub(crate) moments: LevelMoments,
    pub(crate) stats: LevelStats,
    pub(crate) info: LevelInfo,
    /// Every signal driving the filters has zero mean (see `CENTRED_REL`).
    pub(crate) centred: bool,
    /// Per estimated velocity: the cutoff (rad/s) and window half-width (samples) of its
    /// filter on this level.
    pub(crate) velocity: Vec<(f64, usize)>,
}

/// The options of an identification that change its moments or its solve.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DesignOptions {
    pub n_corners: usize,
    pub order: Option<usize>,
    pub drivers: Option<Vec<SignalId>>,
    pub balance: bool,
    pub chunk_len: usize,
    #[serde(with = "exact_one")]
    pub rcond: f64,
    pub hold: Hold,
    pub noise_correction: bool,
    pub column_chains: bool,
    pub keep_rests: bool,
    pub efficient: bool,
    /// With `efficient`, each row weighted by its own estimated error alone
    /// ([`IdentifyOptions::diagonal_weights`]; absent in files written before it existed:
    /// `false`).
    #[serde(default)]
    pub diagonal_weights: bool,
    /// With `efficient`, the weighting re-estimated until the estimate settles
    /// ([`IdentifyOptions::iterate_weights`]; absent in files written before it existed:
    /// `false`).
    #[serde(default)]
    pub iterate_weights: bool,
    /// Rows of the filtered equation (absent in files written before it existed: `false`).
    #[serde(default)]
    pub filtered: bool,
}

/// The design moment statistics are made with, fixed before any piece is measured: the
/// model it is for, the filter corners and order, the time blocks per level, whether the
/// noise corrections are attached, and the options that change the moments.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MomentDesign {
    /// The model's name (for messages).
    pub model: String,
    /// FNV-1a hash (hex) of the model's printed source ([`model_hash`]).
    pub model_hash: String,
    /// Sections per filter chain.
    pub order: usize,
    /// Filter corners, rad/s (in a design's JSON as strings in shortest round-trip form,
    /// which every reader parses to the same bits).
    #[serde(with = "exact")]
    pub corners: Vec<f64>,
    /// How the corners were chosen (for the report).
    pub corners_from: CornerSource,
    /// Time blocks per level (the standard errors' batch means).
    pub n_blocks: usize,
    /// Whether the moments of nonlinear terms carry noise corrections (a measured signal in
    /// them had significant noise in the data the design was made from).
    pub noise_fixes: bool,
    pub options: DesignOptions,
}

/// `f64`s as strings: Rust's shortest round-trip form, parsed back exactly (a JSON reader's
/// numbers may be off by a unit in the last place).
mod exact {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &[f64], s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(v.iter().map(|x| format!("{x:?}")))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
        Vec::<String>::deserialize(d)?
            .iter()
            .map(|t| t.parse::<f64>().map_err(serde::de::Error::custom))
            .collect()
    }
}

/// One `f64` as [`exact`] writes it.
mod exact_one {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&format!("{v:?}"))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        String::deserialize(d)?
            .parse::<f64>()
            .map_err(serde::de::Error::custom)
    }
}

/// FNV-1a (64 bits) of the model's printed source: two models with the same equations,
/// parameters and filter block hash alike, whatever their layout or comments.
pub fn model_hash(ir: &ModelIr) -> String {
    format!("{:016x}", fnv1a(dynid_ir::print::to_source(ir).as_bytes()))
}

/// FNV-1a, 64 bits.
pub(crate) fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

impl MomentDesign {
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        ir: &ModelIr,
        opts: &IdentifyOptions,
        order: usize,
        corners: Vec<f64>,
        corners_from: CornerSource,
        n_blocks: usize,
        noise_fixes: bool,
    ) -> MomentDesign {
        MomentDesign {
            model: ir.name.clone(),
            model_hash: model_hash(ir),
            order,
            corners,
            corners_from,
            n_blocks,
            noise_fixes,
            options: DesignOptions {
                n_corners: opts.n_corners,
                order: opts.order,
                drivers: opts.drivers.clone(),
                balance: opts.balance,
                chunk_len: opts.chunk_len,
                rcond: opts.rcond,
                hold: opts.hold,
                noise_correction: opts.noise_correction,
                column_chains: opts.column_chains,
                keep_rests: opts.keep_rests,
                efficient: opts.efficient,
                diagonal_weights: opts.diagonal_weights,
                iterate_weights: opts.iterate_weights,
                filtered: opts.filtered,
            },
        }
    }

    /// The design pass: the first pass over `levels` (a sample of the data, or all of it)
    /// and the decisions the in-process identification of those levels makes — the
    /// corners (given by `opts` or the model's `filter` block, else designed from the
    /// dominant frequencies and noise floors of the levels), the time blocks (from the
    /// shortest level), the noise corrections (from the levels' noise floors). It reads
    /// every sample once and accumulates no moment.
    pub fn from_data(
        ir: &ModelIr,
        levels: &[&dyn LevelSource],
        opts: &IdentifyOptions,
    ) -> Result<MomentDesign, MomentsError> {
        refuse_shapes(ir)?;
        if opts.input_delay {
            return Err(MomentsError::InputDelay);
        }
        let first = first_pass_all(ir, levels, opts)?;
        Ok(design_levels(ir, opts, &first, levels)?)
    }

    /// The identification options of the design (corners and blocks fixed).
    pub fn identify_options(&self) -> IdentifyOptions {
        let o = &self.options;
        IdentifyOptions {
            corners: Some(self.corners.clone()),
            n_corners: o.n_corners,
            // The order the moments were taken with (the options' fallback may depend on
            // a choice that is not the design's, such as the inputs' delays).
            order: Some(self.order),
            drivers: o.drivers.clone(),
            balance: o.balance,
            n_blocks: Some(self.n_blocks),
            chunk_len: o.chunk_len,
            rcond: o.rcond,
            hold: o.hold,
            noise_correction: o.noise_correction,
            column_chains: o.column_chains,
            keep_rests: o.keep_rests,
            allow_large: false,
            efficient: o.efficient,
            diagonal_weights: o.diagonal_weights,
            iterate_weights: o.iterate_weights,
            filtered: o.filtered,
            // Not a design choice: `moments` refuses it (the pieces' sums are of the
            // model's own columns).
            input_delay: false,
            // The moments are the instrument rows' (or the filtered equation's without
            // the delay), as designed: no choice left (the corners are given anyway).
            auto_rows: false,
        }
    }

    /// Refuse a model other than the design's.
    pub fn check_model(&self, ir: &ModelIr) -> Result<(), MomentsError> {
        let hash = model_hash(ir);
        if hash == self.model_hash {
            return Ok(());
        }
        Err(MomentsError::OtherModel {
            model: ir.name.clone(),
            hash,
            design_model: self.model.clone(),
            design_hash: self.model_hash.clone(),
        })
    }

    /// The first difference from `other` (`None`: the same design).
    pub fn difference(&self, other: &MomentDesign) -> Option<String> {
        let show = |v: &dyn std::fmt::Debug| format!("{v:?}");
        let fields: [(&str, String, String); 7] = [
            (
                "model",
                format!("{} ({})", self.model, self.model_hash),
                format!("{} ({})", other.model, other.model_hash),
            ),
            ("filter order", show(&self.order), show(&other.order)),
            ("corners (rad/s)", show(&self.corners), show(&other.corners)),
            (
                "time blocks per level",
                show(&self.n_blocks),
                show(&other.n_blocks),
            ),
            (
                "noise corrections",
                show(&self.noise_fixes),
                show(&other.noise_fixes),
            ),
            ("options", show(&self.options), show(&other.options)),
            (
                "corner source",
                show(&self.corners_from),
                show(&other.corners_from),
            ),
        ];
        fields
            .into_iter()
            .find(|(_, a, b)| a != b)
            .map(|(what, a, b)| format!("{what}: {a} against {b}"))
    }
}

/// Moment statistics: the measured pieces (one per level of the pooled problem) of one
/// design. See the module documentation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MomentStats {
    pub(crate) design: MomentDesign,
    pub(crate) levels: Vec<LevelPiece>,
}

impl MomentStats {
    /// Measure `levels` (each a record, one level of the pooled problem) with `design`:
    /// the first pass and the streamed pass of the in-process identification, with the
    /// design's corners, blocks and noise corrections instead of decisions of its own.
    pub fn measure(
        ir: &ModelIr,
        levels: &[&dyn LevelSource],
        design: &MomentDesign,
        allow_large: bool,
    ) -> Result<MomentStats, MomentsError> {
        refuse_shapes(ir)?;
        design.check_model(ir)?;
        let mut opts = design.identify_options();
        opts.allow_large = allow_large;
        let first = first_pass_all(ir, levels, &opts)?;
        if first.bank.order != design.order {
            return Err(MomentsError::OtherDesign {
                detail: format!(
                    "filter order: {} for this model against {} in the design",
                    first.bank.order, design.order
                ),
            });
        }
        super::measure::check_against(design, &first, levels)?;
        let tape = Tape::compile(ir, &ir.eval_roots());
        let (pieces, _) = measure_pieces(ir, &tape, levels, &opts, design, first)?;
        Ok(MomentStats {
            design: design.clone(),
            levels: pieces,
        })
    }

    /// The design of the statistics.
    pub fn design(&self) -> &MomentDesign {
        &self.design
    }

    /// The number of levels (pieces) merged.
    pub fn len(&self) -> usize {
        self.levels.len()
    }

    /// Whether no level is held (never the case of measured or decoded statistics).
    pub fn is_empty(&self) -> bool {
        self.levels.is_empty()
    }

    /// Where each level came from (its file, in order).
    pub fn origins(&self) -> Vec<String> {
        self.levels.iter().map(|l| l.info.origin.clone()).collect()
    }

    /// Merge `other` into these statistics: its levels follow these. Refused for another
    /// design or model.
    pub fn merge(mut self, other: MomentStats) -> Result<MomentStats, MomentsError> {
        if let Some(detail) = self.design.difference(&other.design) {
            return Err(MomentsError::OtherDesign { detail });
        }
        self.levels.extend(other.levels);
        Ok(self)
    }

    /// Merge all statistics in order.
    pub fn merge_all(
        parts: impl IntoIterator<Item = MomentStats>,
    ) -> Result<MomentStats, MomentsError> {
        let mut it = parts.into_iter();
        let first = it.next().ok_or(MomentsError::Empty)?;
        it.try_fold(first, MomentStats::merge)
    }

    /// Solve the statistics into the identification of their levels pooled, with the
    /// warnings of the fit that the moments show (the probes that re-measure a changed
    /// model need the data: from moments alone a large residual is not traced to a fixed
    /// mass or an offset).
    pub fn identify(&self, ir: &ModelIr) -> Result<Identification, MomentsError> {
        refuse_shapes(ir)?;
        self.design.check_model(ir)?;
        let m = measurement_of(ir, &self.design, self.levels.clone(), Default::default())?;
        let mut id = m.identify_pooled();
        id.fit_warnings = super::guard::check(&m, &id, &[], &self.design.identify_options());
        Ok(id)
    }
}

/// Models with shape functions are identified by a profile over many designs: not from
/// moment statistics.
fn refuse_shapes(ir: &ModelIr) -> Result<(), MomentsError> {
    if ir.shapes.is_empty() {
        Ok(())
    } else {
        Err(MomentsError::Shapes {
            model: ir.name.clone(),
        })
    }
}

/// Why moment statistics cannot be made, read, merged or solved.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum MomentsError {
    #[error("{origin}: not a moment statistics file (no `DYNIDMOM` header)")]
    #[diagnostic(
        code(dynid::moments::not_moments),
        help("give files written by `dynid moments MODEL DATA... --out PART.dynm`")
    )]
    NotMoments { origin: String },
    #[error("{origin}: moment statistics of format version {found}; this dynid reads version {supported}")]
    #[diagnostic(
        code(dynid::moments::version),
        help("make the statistics again with this version of dynid (`dynid moments`)")
    )]
    Version {
        origin: String,
        found: u32,
        supported: u32,
    },
    #[error("{origin}: the moment statistics are truncated ({have} bytes of {need})")]
    #[diagnostic(
        code(dynid::moments::truncated),
        help("the file was cut short (an interrupted copy?): copy it again or make it again")
    )]
    Truncated {
        origin: String,
        have: usize,
        need: usize,
    },
    #[error("{origin}: the moment statistics are corrupt ({detail})")]
    #[diagnostic(
        code(dynid::moments::corrupt),
        help("the file was changed after it was written: make it again with `dynid moments`")
    )]
    Corrupt { origin: String, detail: String },
    #[error("the statistics were made for the model `{design_model}` (hash {design_hash}), not for `{model}` (hash {hash})")]
    #[diagnostic(
        code(dynid::moments::other_model),
        help("give the model file the statistics were made with; after any change of the model make them again")
    )]
    OtherModel {
        model: String,
        hash: String,
        design_model: String,
        design_hash: String,
    },
    #[error("moment statistics of different designs cannot be merged: {detail}")]
    #[diagnostic(
        code(dynid::moments::other_design),
        help("make every piece with one design: `dynid moments MODEL SAMPLE... --design-only --out design.json`, then `dynid moments MODEL DATA --design design.json` for each piece")
    )]
    OtherDesign { detail: String },
    #[error("the inputs' delays are not estimated from moment statistics: their columns are not among the model's")]
    #[diagnostic(
        code(dynid::moments::input_delay),
        help(
            "identify from the data to estimate them: `dynid identify MODEL DATA... --input-delay`"
        )
    )]
    InputDelay,
    #[error("no moment statistics to merge")]
    #[diagnostic(code(dynid::moments::empty), help("give at least one .dynm file"))]
    Empty,
    #[error("the model `{model}` has shape functions: it is identified by a profile over many filter designs, not from one design's moment statistics")]
    #[diagnostic(
        code(dynid::moments::shapes),
        help("identify it from the data: `dynid identify MODEL DATA...`")
    )]
    Shapes { model: String },
    #[error(transparent)]
    #[diagnostic(transparent)]
    Identify(#[from] IdentifyError),
}
