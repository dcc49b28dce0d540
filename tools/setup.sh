#!/usr/bin/env bash
# Installs what the build and the tests need beyond the Rust toolchain, idempotently:
# - libclang (Debian's libclang-dev): the `fmi` crate, our independent FMU importer in
#   the Rust tests, runs bindgen when it builds;
# - a Python venv in .venv with fmpy, pytest, lxml and libcosimpy (DNV's co-simulation
#   engine, for tests/python/test_engines.py) (requirements in tools/requirements.txt).
set -euo pipefail
cd "$(dirname "$0")/.."

if ! dpkg -s libclang-dev >/dev/null 2>&1; then
    echo "setup: installing libclang-dev" >&2
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libclang-dev >/dev/null
fi

if [ ! -x .venv/bin/python ] || ! .venv/bin/python -c "import fmpy, pytest, lxml, dask.distributed, matplotlib, tqdm, libcosimpy" 2>/dev/null; then
    echo "setup: creating .venv with fmpy and pytest" >&2
    python3 -m venv .venv
    .venv/bin/pip install -q --disable-pip-version-check -r tools/requirements.txt
fi
