//! The `plugflow` command line: `run`, `sweep`, `study`, `crosscheck`, `validate` (one file
//! each under `src/cli/`).

mod cli;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "plugflow",
    version,
    about = "Gas–grain co-simulation of dense-phase pneumatic conveying"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene and write results/<name>/summary.json.
    Run(cli::run::RunArgs),
    /// Run every combination of the --vary lists as parallel processes; write sweep.csv and
    /// characteristic.png into the output folder (default results/<scene name>_sweep/).
    Sweep(cli::sweep::SweepArgs),
    /// Run a scene on several DEM engines and write a side-by-side report (crosscheck.md,
    /// crosscheck.png) into the output folder (default results/<scene name>_crosscheck/).
    Crosscheck(cli::crosscheck::CrosscheckArgs),
    /// Error against run time: run every combination of the --vary lists, measure each
    /// observable's error against an exact value (--exact) or the finest variant, and write
    /// study.csv, study.md and study.png (error vs wall time, Pareto front) into the output
    /// folder (default results/<scene name>_study/).
    Study(cli::study::StudyArgs),
    /// Check a scene without running it; exit code 2 and the field at fault when wrong.
    Validate(cli::validate::ValidateArgs),
}

fn main() -> ExitCode {
    let command = Cli::parse().command;
    let ranks = plugflow::setup::ranks::launched();
    if ranks.size > 1 && !matches!(command, Command::Run(_) | Command::Validate(_)) {
        // sweep, study and crosscheck start runs of their own: start them without mpirun,
        // or run each variant under mpirun with `plugflow run`.
        eprintln!(
            "error: under mpirun ({} ranks) plugflow runs `run` and `validate` only; start \
             sweep, study and crosscheck without mpirun",
            ranks.size
        );
        return ExitCode::from(2);
    }
    cli::finish(match command {
        Command::Run(a) => cli::run::main(a),
        Command::Sweep(a) => cli::sweep::main(a),
        Command::Crosscheck(a) => cli::crosscheck::main(a),
        Command::Study(a) => cli::study::main(a),
        Command::Validate(a) => cli::validate::main(a),
    })
}
