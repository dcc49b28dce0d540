#!/usr/bin/env bash
# The main job: build, package the five FMUs into out/fmu, and run the thesis checks of
# the bench physics (step responses, closed-loop sweep) into out/.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --workspace
./target/release/hbench fmu --out out/fmu --force
cargo run --release -q -p hydrobench-model --example validate
