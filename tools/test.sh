#!/usr/bin/env bash
# The project's test command: builds everything, packages the FMUs into target/fmu,
# runs the Rust tests (model physics, FMI importer) and the Python tests (fmpy).
#
# The two suites run side by side: on 2 cores the Rust suite keeps both busy only while
# its short tests last, and the Python suite (about 220 CPU s, of which the fuzzer's
# fixed 80 s budget) fills a core its long blind studies leave idle. Measured on this
# machine (2026-11-26, docs/gap.md session 19): one after the other the hbench tests
# took 753 s and pytest 232 s; side by side 757 s for both, pytest 385 s of it. The
# hbench tests' CPU by test is in docs/gap.md, session 31.
set -euo pipefail
cd "$(dirname "$0")/.."
# The Debian packages first: the build needs libclang-dev (the `fmi` crate's bindgen;
# hbench's co-simulation master imports FMUs through it). The Python venv waits on the
# network and the build on the CPU, so they overlap; only the tests need the venv.
bash tools/setup.sh debian
venvlog=$(mktemp)
pylog=$(mktemp)
trap 'rm -f "$venvlog" "$pylog"' EXIT
bash tools/setup.sh python >"$venvlog" 2>&1 &
venv=$!
cargo build --release --workspace
if ! wait "$venv"; then
    cat "$venvlog" >&2
    echo "set-up of the Python venv failed (tools/setup.sh python)" >&2
    exit 1
fi
cat "$venvlog" >&2
./target/release/hbench fmu --out target/fmu --force
# every test binary built before either suite starts, so no test competes with rustc
cargo test --release --workspace --no-run
.venv/bin/python -m pytest -q tests/python >"$pylog" 2>&1 &
python_suite=$!
rust=0
cargo test --release --workspace || rust=$?
python=0
wait "$python_suite" || python=$?
echo "--- Python suite (tests/python), run beside the Rust suite ---"
cat "$pylog"
if ((rust != 0 || python != 0)); then
    echo "tests failed: Rust suite exit $rust, Python suite exit $python" >&2
    exit 1
fi
