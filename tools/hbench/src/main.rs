//! `hbench`: the HydroBench command line.

mod package;

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
        /// The compiled FMI library (libhbfmu.so); by default the one next to this program
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
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("hbench: {e}");
            ExitCode::FAILURE
        }
    }
}
