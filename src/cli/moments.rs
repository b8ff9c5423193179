//! `dynid moments MODEL DATA... --out PART.dynm`: the moment statistics of some records (a
//! piece of a larger data set), to be merged with others and solved by `dynid identify
//! MODEL --from PART.dynm...`; `--design-only` writes the design the pieces share.

use super::common::{check_outputs, inputs, load_model, write_atomically, CsvArgs, EstimatorArgs};
use dynid_runtime::data::{FileSource, LevelSource};
use dynid_runtime::ident::{MomentDesign, MomentStats, MomentsError};
use miette::miette;
use std::path::{Path, PathBuf};

const LONG_HELP: &str = "\
Measures the records DATA (one level of the pooled problem each) as identification does —
the first pass, then every sample once through the filters — and writes what it accumulates,
the moment statistics, to a binary file (.dynm, every number exact: 0.3 to 0.8 MB per
record of two_mass, bounded by the at most 80 time blocks whatever the record's length). Statistics of the same design merge exactly:
`dynid identify MODEL --from a.dynm b.dynm ...` solves them into the identification of all
their records given together, so a data set too large for one machine is reduced piece by
piece (on any batch system or shell pipeline) and solved on one.

Everything identification decides from all levels at once is fixed before: the filter
corners (the model's `filter` block, --filter-corners, or designed from the data), the time
blocks per level (from the shortest record) and the noise corrections. Make that design once
from a sample of the data and give it to every piece.

Example:

  dynid moments models/two_mass.dyn data/level_1.csv --design-only --out design.json
  dynid moments models/two_mass.dyn data/level_1.csv --design design.json --out p1.dynm
  dynid moments models/two_mass.dyn data/level_2.csv data/level_3.csv \\
      --design design.json --out p23.dynm
  dynid identify models/two_mass.dyn --from p1.dynm p23.dynm

Without --design the statistics carry the design of their own records (the same as
identifying those records). Statistics of another design or another model are refused by
the merge, as are damaged files. A record cut into pieces becomes that many records, each
with its own filter start-up: the design must fit the shortest piece. docs/distributed.md
describes the file and the merge.";

/// Arguments of `dynid moments`.
#[derive(clap::Args, Debug)]
#[command(after_long_help = LONG_HELP, allow_negative_numbers = true)]
pub struct Args {
    /// The model file.
    pub model: PathBuf,
    /// One data file per record (level): CSV, MATLAB .mat, HDF5 or Parquet, as for
    /// `identify`.
    #[arg(required = true)]
    pub data: Vec<PathBuf>,
    /// Write the statistics (or, with --design-only, the design as JSON) to this file.
    #[arg(long, value_name = "OUT")]
    pub out: PathBuf,
    /// Measure with this design (written by --design-only) instead of one made from DATA.
    #[arg(
        long,
        value_name = "DESIGN.json",
        conflicts_with_all = ["design_only", "filter_corners", "balance", "no_noise_correction", "column_chains", "keep_rests", "filtered_equation", "weighted_rows", "input_delay"]
    )]
    pub design: Option<PathBuf>,
    /// Write only the design made from DATA (a sample of the data set), as JSON: corners,
    /// time blocks, noise corrections and options. Reads DATA once, accumulates nothing.
    #[arg(long = "design-only")]
    pub design_only: bool,
    #[command(flatten)]
    pub csv: CsvArgs,
    #[command(flatten)]
    pub estimator: EstimatorArgs,
    /// Run even when the estimated memory is above the safety limit (8 GB).
    #[arg(long)]
    pub allow_large: bool,
}

pub fn run(args: Args) -> miette::Result<()> {
    let what = if args.design_only {
        "the design"
    } else {
        "the moment statistics"
    };
    check_outputs(
        [(Some(args.out.as_path()), what)],
        inputs(&args.model, &args.data).chain(args.design.as_deref()),
    )?;
    let ir = load_model(&args.model)?;
    let csv = args.csv.options(&ir)?;
    let sources = args
        .data
        .iter()
        .map(|p| FileSource::open(p, &ir, &csv))
        .collect::<Result<Vec<_>, _>>()?;
    let levels: Vec<&dyn LevelSource> = sources.iter().map(|s| s as &dyn LevelSource).collect();
    let design = match &args.design {
        Some(p) => read_design(p, &ir)?,
        None => {
            let opts = args.estimator.options(args.allow_large);
            MomentDesign::from_data(&ir, &levels, &opts)?
        }
    };
    if args.design_only {
        let text = serde_json::to_string_pretty(&design).map_err(|e| {
            miette!(
                code = "dynid::output::write",
                "cannot encode the design: {e}"
            )
        })?;
        write_atomically(&args.out, format!("{text}\n").as_bytes())?;
        eprintln!(
            "design of `{}`: {} corners ({} … {} rad/s), {} time blocks per record → {}",
            design.model,
            design.corners.len(),
            design.corners.first().copied().unwrap_or(0.0),
            design.corners.last().copied().unwrap_or(0.0),
            design.n_blocks,
            args.out.display()
        );
        return Ok(());
    }
    let stats = MomentStats::measure(&ir, &levels, &design, args.allow_large)?;
    let bytes = stats.to_bytes();
    write_atomically(&args.out, &bytes)?;
    eprintln!(
        "moment statistics of {} record(s), {} bytes → {}",
        stats.len(),
        bytes.len(),
        args.out.display()
    );
    Ok(())
}

/// A design written by `--design-only`, checked against the model.
fn read_design(path: &Path, ir: &dsl_parser::ir::ModelIr) -> miette::Result<MomentDesign> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        miette!(
            code = "dynid::moments::design",
            help = "give the file written by `dynid moments MODEL SAMPLE... --design-only --out DESIGN.json`",
            "cannot read the design `{}`: {e}",
            path.display()
        )
    })?;
    let design: MomentDesign = serde_json::from_str(&text).map_err(|e| {
        miette!(
            code = "dynid::moments::design",
            help = "give the file written by `dynid moments MODEL SAMPLE... --design-only --out DESIGN.json`, unchanged",
            "{}: not a moment design ({e})",
            path.display()
        )
    })?;
    design.check_model(ir)?;
    Ok(design)
}

/// Read and merge the statistics files `paths` in order (for `identify --from`): a file of
/// another design than those before it is refused, named.
pub fn read_merged(paths: &[PathBuf]) -> miette::Result<MomentStats> {
    let mut merged: Option<MomentStats> = None;
    for p in paths {
        let bytes = std::fs::read(p).map_err(|e| {
            miette!(
                code = "dynid::moments::read",
                help = "give files written by `dynid moments MODEL DATA... --out PART.dynm`",
                "cannot read `{}`: {e}",
                p.display()
            )
        })?;
        let part = MomentStats::from_bytes(&bytes, &p.display().to_string())?;
        merged = Some(match merged {
            None => part,
            Some(m) => m.merge(part).map_err(|e| match e {
                MomentsError::OtherDesign { detail } => MomentsError::OtherDesign {
                    detail: format!("{} against the files before it: {detail}", p.display()),
                },
                e => e,
            })?,
        });
    }
    Ok(merged.ok_or(MomentsError::Empty)?)
}
