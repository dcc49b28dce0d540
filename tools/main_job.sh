#!/usr/bin/env bash
# The main job: build, package the five FMUs into out/fmu, and run the thesis checks of
# the bench physics (step responses, closed-loop sweep) into out/.
set -euo pipefail
cd "$(dirname "$0")/.."
# what the build needs beyond the Rust toolchain (libclang-dev for the fmi crate's
# bindgen, the Python venv), as the test command installs it: a fresh machine has neither
bash tools/setup.sh
cargo build --release --workspace
./target/release/hbench fmu --out out/fmu --force
cargo run --release -q -p hydrobench-model --example validate
