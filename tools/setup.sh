#!/usr/bin/env bash
# Installs what the build and the tests need beyond the Rust toolchain, idempotently:
# - Debian's libclang-dev: the `fmi` crate, our independent FMU importer in the Rust
#   tests, runs bindgen when it builds;
# - Debian's valgrind: tests/python/test_valgrind.py runs the FMUs under memcheck;
# - a Python venv in .venv with fmpy, pytest, lxml, scipy (the peer simulator),
#   libcosimpy (DNV's co-simulation engine, tests/python/test_engines.py) and the rest
#   of tools/requirements.txt.
set -euo pipefail
cd "$(dirname "$0")/.."

missing=()
for pkg in libclang-dev valgrind; do
    dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg")
done
if ((${#missing[@]})); then
    echo "setup: installing ${missing[*]}" >&2
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi

if [ ! -x .venv/bin/python ] || ! .venv/bin/python -c "import fmpy, pytest, lxml, dask.distributed, matplotlib, tqdm, scipy, libcosimpy" 2>/dev/null; then
    echo "setup: creating .venv with fmpy and pytest" >&2
    python3 -m venv .venv
    .venv/bin/pip install -q --disable-pip-version-check -r tools/requirements.txt
fi
