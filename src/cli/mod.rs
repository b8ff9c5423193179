//! Subcommands. Each lives in its own module with an `Args` struct and a `run` function.

use clap::{Parser, Subcommand};

pub mod common;
pub mod compile;
pub mod demo;
pub mod detect;
pub mod diagnose;
pub mod duplicates;
pub mod excitation;
pub mod fleet;
pub mod frf;
pub mod identify;
pub mod moments;
pub mod silverbox;
pub mod simulate;

/// Detect, identify and diagnose nonlinear force elements in mechanical models from
/// random-excitation data (covariance method).
#[derive(Parser, Debug)]
#[command(name = "dynid", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Compile a .dyn model: equations of motion, parameters, least-squares columns.
    Compile(compile::Args),
    /// Simulate a model at its excitation levels (or driven by a measured input).
    Simulate(simulate::Args),
    /// Identify the unknown parameters from measured data, one CSV per excitation level.
    Identify(identify::Args),
    /// Moment statistics of some records, to merge and solve with `identify --from`.
    Moments(moments::Args),
    /// Detect which elements of a linear model are nonlinear, from one CSV per level.
    Detect(detect::Args),
    /// The Silverbox benchmark on the real measurement (identify, free-run RMS, arrow levels).
    Silverbox(silverbox::Args),
    /// Diagnose the sim-to-real gap: where, which unmodelled effect, how far it shrinks.
    Diagnose(diagnose::Args),
    /// Simulate a system with friction and diagnose the friction-free model against it.
    Demo(demo::Args),
    /// Test machines of one model, each identified on its own, against their fleet.
    Fleet(fleet::Args),
}

pub fn run(cli: Cli) -> miette::Result<()> {
    match cli.command {
        Command::Compile(a) => compile::run(a),
        Command::Simulate(a) => simulate::run(a),
        Command::Identify(a) => identify::run(a),
        Command::Moments(a) => moments::run(a),
        Command::Detect(a) => detect::run(a),
        Command::Silverbox(a) => silverbox::run(a),
        Command::Diagnose(a) => diagnose::run(a),
        Command::Demo(a) => demo::run(a),
        Command::Fleet(a) => fleet::run(a),
    }
}
