#!/usr/bin/env bash
# The project's test command: builds everything, packages the FMUs into target/fmu,
# runs the Rust tests (model physics, FMI importer) and the Python tests (fmpy).
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
cargo build --release --workspace
./target/release/hbench fmu --out target/fmu --force
cargo test --release --workspace
.venv/bin/python -m pytest -q tests/python
