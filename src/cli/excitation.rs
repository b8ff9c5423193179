//! The test-signal options of `dynid simulate`: multisines and sine sweeps instead of the
//! models' random form filters.

use dynid_runtime::sim::{Grid, Phases, SweepLaw, TestSignal};

/// Which excitation drives the excited inputs.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SignalKind {
    /// The model's `excite` form filters (level = white-noise intensity).
    Random,
    /// A multisine on the lines of --band-hz (level = RMS of the input).
    Multisine,
    /// A sine sweep over --band-hz (level = amplitude of the input).
    Sweep,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum GridArg {
    Full,
    Odd,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum PhasesArg {
    Random,
    Schroeder,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum LawArg {
    Linear,
    Log,
}

/// The excitation options of `simulate`.
#[derive(clap::Args, Debug, Clone)]
pub struct SignalArgs {
    /// Excitation of the excited inputs: the model's random form filters, a multisine or
    /// a sine sweep (see below for what a level means for each).
    #[arg(long, value_enum, default_value_t = SignalKind::Random, conflicts_with = "input")]
    pub signal: SignalKind,
    /// Band of the multisine or sweep in Hz (not rad/s): LOW,HIGH (a sweep runs from the
    /// first to the second, so HIGH,LOW sweeps down).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "LOW_HZ,HIGH_HZ",
        conflicts_with = "input"
    )]
    pub band_hz: Option<Vec<f64>>,
    /// Whole multisine periods (or sweeps) in each recorded --duration.
    #[arg(long, default_value_t = 4, value_name = "N", conflicts_with = "input")]
    pub periods: usize,
    /// Multisine frequency grid: every harmonic of 1/period in the band, or the odd ones.
    #[arg(long, value_enum, default_value_t = GridArg::Full, conflicts_with = "input")]
    pub grid: GridArg,
    /// Multisine phases: random (per level) or Schroeder's (low crest factor).
    #[arg(long, value_enum, default_value_t = PhasesArg::Random, conflicts_with = "input")]
    pub phases: PhasesArg,
    /// Sweep law: frequency linear or logarithmic in time.
    #[arg(long, value_enum, default_value_t = LawArg::Log, conflicts_with = "input")]
    pub sweep_law: LawArg,
}

impl Default for SignalArgs {
    /// The form filters (no test signal), with the flags' defaults.
    fn default() -> Self {
        SignalArgs {
            signal: SignalKind::Random,
            band_hz: None,
            periods: 4,
            grid: GridArg::Full,
            phases: PhasesArg::Random,
            sweep_law: LawArg::Log,
        }
    }
}

impl SignalArgs {
    /// The test signal asked for (`None`: the form filters).
    pub fn signal(&self) -> miette::Result<Option<TestSignal>> {
        if self.signal == SignalKind::Random {
            return Ok(None);
        }
        let Some(&[lo, hi]) = self.band_hz.as_deref() else {
            miette::bail!(
                code = "dynid::simulate::option",
                help = "give the band in Hz as two numbers, e.g. `--band-hz 0.1,3`",
                "`--signal {}` needs `--band-hz LOW,HIGH`",
                if self.signal == SignalKind::Multisine {
                    "multisine"
                } else {
                    "sweep"
                }
            );
        };
        Ok(Some(match self.signal {
            SignalKind::Multisine => TestSignal::Multisine {
                f_min_hz: lo.min(hi),
                f_max_hz: lo.max(hi),
                periods: self.periods,
                grid: match self.grid {
                    GridArg::Full => Grid::Full,
                    GridArg::Odd => Grid::Odd,
                },
                phases: match self.phases {
                    PhasesArg::Random => Phases::Random,
                    PhasesArg::Schroeder => Phases::Schroeder,
                },
            },
            _ => TestSignal::Sweep {
                f_start_hz: lo,
                f_end_hz: hi,
                law: match self.sweep_law {
                    LawArg::Linear => SweepLaw::Linear,
                    LawArg::Log => SweepLaw::Log,
                },
                sweeps: self.periods,
            },
        }))
    }
}
