//! `hbench`: the HydroBench command line.

mod bench;
mod cosim;
mod package;
mod plot;
mod simulate;
mod sweep;
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
    /// Run a thesis experiment on the full bench model (thesis parameters, mode 3 unless
    /// told otherwise) and write per run a CSV of the traces (SI units), per experiment an
    /// SVG figure and a JSON file of the metrics (transient max/RMS/STD, static mean/STD,
    /// peak pressure, supply energy, pressure tracking). `--list` shows the experiments.
    /// With --inputs-only, write instead inputs.csv and scenario.json: the input table and
    /// start values that make bench_closed_loop.fmu run the same experiment.
    Simulate {
        /// Experiment: steps, sine, moves, payloads, gains, dao2, laws, modes
        #[arg(long, required_unless_present = "list")]
        scenario: Option<String>,
        /// List the experiments and exit
        #[arg(long)]
        list: bool,
        /// Directory for the CSV, SVG and JSON files (created if missing)
        #[arg(long, default_value = "out/simulate")]
        out: PathBuf,
        /// Bench parameter file (TOML) instead of the built-in thesis bench
        #[arg(long)]
        parameters: Option<PathBuf>,
        /// Working mode 1, 2 or 3
        #[arg(long, value_parser = simulate::parse_mode)]
        mode: Option<hbmodel::Mode>,
        /// Control law: proportional, y_lambda, p_y, model_free, restricted_model
        #[arg(long, value_parser = simulate::parse_law)]
        law: Option<hbmodel::control::config::LawKind>,
        /// Thesis gain set: low or high (backstepping c1..c4; Kp 1169 or 5200 V/m;
        /// model-free Kp 30 or 250 V/m)
        #[arg(long, value_parser = simulate::parse_gains)]
        gains: Option<bool>,
        /// Payload on the piston, unknown to the law (kg)
        #[arg(long)]
        payload: Option<f64>,
        /// DAO2 gains as Kd0,Kd1 (1/s); the thesis uses 200,80 and 60,25
        #[arg(long, value_parser = simulate::parse_dao2)]
        dao2: Option<[f64; 2]>,
        /// Feed the law with the exact states instead of DAO2 estimates
        #[arg(long)]
        exact_states: bool,
        /// Sine frequency (Hz) for the sine experiment
        #[arg(long)]
        frequency: Option<f64>,
        /// Computation delay between a sample and its command (s), below 1 ms
        #[arg(long)]
        computation_delay: Option<f64>,
        /// Sampling period of the law (s); 1e-3 on the thesis's board
        #[arg(long)]
        period: Option<f64>,
        /// Write the closed-loop FMU's inputs and start values instead of simulating
        #[arg(long)]
        inputs_only: bool,
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
    /// Co-simulate the bench from its component FMUs (two servovalves, manifold,
    /// actuator) as bench.ssp wires them, under the thesis's 1 kHz proportional control
    /// (Kp = 1169 V/m), in Jacobi and Gauss-Seidel order, and compare with bench.fmu:
    /// the 7th-order -10/+10 mm move and a 3.4 mm 50 Hz sine, per mode and communication
    /// step. Prints the error table; writes cosim_errors.json, cosim_traces.csv and the
    /// reference trajectories (reference_<experiment>.csv) into --out.
    Cosim(cosim::CosimArgs),
    /// Parameter studies and robustness sweeps of an FMU (grid, random, Latin hypercube)
    /// on all cores or a Dask cluster, resumable; runs tools/sweep in the project's venv.
    /// `hbench sweep --help` for the options.
    #[command(disable_help_flag = true)]
    Sweep {
        /// Arguments of the sweep runner (--study FILE --out DIR [--scheduler ADDRESS] ...)
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
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
        Command::Simulate { list: true, .. } => {
            print!("{}", simulate::list());
            Ok(())
        }
        Command::Simulate {
            scenario,
            out,
            parameters,
            mode,
            law,
            gains,
            payload,
            dao2,
            exact_states,
            frequency,
            computation_delay,
            period,
            inputs_only,
            ..
        } => simulate::main(&simulate::Request {
            scenario: scenario.unwrap_or_default(),
            out,
            parameters,
            overrides: hbmodel::control::scenario::Overrides {
                mode,
                law,
                high_gains: gains,
                payload,
                dao2,
                source: exact_states.then_some(hbmodel::control::sampled::StateSource::Exact),
                frequency,
                computation_delay,
                period,
            },
            inputs_only,
        }),
        Command::Bench { seconds, json } => bench::main(seconds, json),
        Command::Cosim(args) => cosim::main(args),
        Command::Sweep { args } => sweep::main(&args),
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
