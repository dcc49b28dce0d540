//! `hbench`: the HydroBench command line.

mod bench;
mod package;
mod tables;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "hbench", version, about = "HydroBench: an open virtual prototype of the INSA Lyon electro-hydraulic test bench", long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Package the FMI 2.0 Co-Simulation FMUs (servovalve, manifold, actuator, bench,
    /// controller) into DIR, each with its generated modelDescription.xml and the
    /// shared library under binaries/<platform>/. Existing FMUs in DIR are replaced only
    /// with --force.
    Fmu {
        /// Directory to write the .fmu files into (created if missing)
        #[arg(long, default_value = "out/fmu")]
        out: PathBuf,
        /// The compiled FMI library (libhbfmu.so); by default hbench builds it in release
        /// mode from its workspace (or, installed alone, uses the one next to itself)
        #[arg(long)]
        lib: Option<PathBuf>,
        /// A parameter file (TOML, the model's parameter tree) to ship as
        /// resources/parameters.toml, overriding the built-in thesis values
        #[arg(long)]
        parameters: Option<PathBuf>,
        /// Replace FMUs already in DIR
        #[arg(long)]
        force: bool,
        /// Also write each modelDescription.xml next to the FMUs
        #[arg(long)]
        xml: bool,
    },
    /// Regenerate the thesis's control result tables (Tables 5.1, 6.1, 7.1, 7.2 form) by
    /// simulating every law on the full bench, the thesis's values side by side; writes
    /// tables.md and tables.json into DIR.
    Tables {
        /// Directory for tables.md and tables.json
        #[arg(long, default_value = "docs")]
        out: PathBuf,
    },
    /// Measure the speed of the bench model: simulated seconds per CPU second for the
    /// bench in mode 3 under proportional control following +-10 mm moves, static and
    /// second-order servovalve, rtol 1e-6, and the deviation from an rtol 1e-9 run.
    Bench {
        /// Simulated time per run (s)
        #[arg(long, default_value_t = 1.0)]
        seconds: f64,
        /// Print JSON instead of the table
        #[arg(long)]
        json: bool,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Fmu {
            out,
            lib,
            parameters,
            force,
            xml,
        } => package::run(&out, lib, parameters, force, xml),
        Command::Bench { seconds, json } => bench::main(seconds, json),
        Command::Tables { out } => tables::main(&out),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("hbench: {e}");
            ExitCode::FAILURE
        }
    }
}
