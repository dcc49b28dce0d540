#!/usr/bin/env bash
# Installs what the build and the tests need beyond the Rust toolchain, idempotently:
# - Debian's libclang-dev: the `fmi` crate (hbench's co-simulation master, and our
#   independent FMU importer in the Rust tests) runs bindgen when it builds;
# - Debian's valgrind: tests/python/test_valgrind.py runs the FMUs under memcheck;
# - a Python venv in .venv with fmpy, pytest, lxml, scipy (the peer simulator),
#   libcosimpy (DNV's co-simulation engine, tests/python/test_engines.py) and the rest
#   of tools/requirements.txt.
#
# `setup.sh debian` installs the Debian packages only, `setup.sh python` the venv only
# (tools/test.sh builds while the venv installs); no argument: both.
set -euo pipefail
cd "$(dirname "$0")/.."
part=${1:-all}
case "$part" in
debian | python | all) ;;
*)
    echo "setup: unknown part '$part' (debian, python, or none for both)" >&2
    exit 2
    ;;
esac

if [ "$part" != python ]; then
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
fi

if [ "$part" != debian ]; then
    if [ ! -x .venv/bin/python ] || ! .venv/bin/python -c "import fmpy, pytest, lxml, dask.distributed, matplotlib, tqdm, scipy, libcosimpy" 2>/dev/null; then
        echo "setup: creating .venv with fmpy and pytest" >&2
        python3 -m venv .venv
        .venv/bin/pip install -q --disable-pip-version-check -r tools/requirements.txt
    fi
fi
