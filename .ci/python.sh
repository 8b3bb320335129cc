#!/usr/bin/env bash
# CI for the Python module and the Mitsuba 3 plugin (bindings/python): builds
# the module with maturin into a venv, builds the CLI the tests compare
# against, and runs pytest (bit identity with the Rust API, errors, and
# renders against Mitsuba's built-in BSDFs in scalar_rgb and llvm_ad_rgb).
# Its lints run here (after maturin's build, whose build scripts and proc
# macros they reuse); its formatting is .ci/run's (cargo fmt --all).
#
# Runs from any directory, on a fresh Debian bookworm with Python 3.11 and
# rustup's cargo. As root it installs what it needs with apt-get (libLLVM 19
# for Mitsuba's llvm_ad_rgb: the system's older libLLVM aborts Dr.Jit);
# otherwise those packages must already be there. The venv is
# $STRATA_VENV (default target/venv); set STRATA_SKIP_APT=1 to skip apt-get.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never

PYTHON=${PYTHON:-python3}
VENV=${STRATA_VENV:-target/venv}

if [ "${STRATA_SKIP_APT:-0}" != 1 ] && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  echo "== apt-get install libllvm19 python3-venv"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19 python3-venv python3-pip >/dev/null
fi

echo "== venv $VENV"
if [ ! -x "$VENV/bin/python" ]; then
  "$PYTHON" -m venv "$VENV"
fi
# shellcheck disable=SC1091
source "$VENV/bin/activate"
python -m pip install -q --upgrade pip
python -m pip install -q mitsuba==3.9.1 drjit==1.5.0 numpy==2.4.6 maturin==1.16.0 pytest==9.2.0 pytest-xdist==3.8.0
# .ci/run installs ahead, in the background, while the Rust stages run.
if [ "${1:-}" = --install-only ]; then
  exit 0
fi

echo "== maturin develop --release (the module strata_bsdf)"
# (pyo3's features of shared dependencies differ from the workspace build's, so
# the library compiles again here.)
maturin develop --release -m bindings/python/Cargo.toml

echo "== cargo clippy --release -p strata-bsdf-python -- -D warnings"
cargo clippy --release -p strata-bsdf-python --all-targets -- -D warnings

echo "== cargo build --release -p strata-cli (the tests compare with it)"
cargo build --release -p strata-cli
TARGET_DIR=${CARGO_TARGET_DIR:-target}
export STRATA_CLI="$TARGET_DIR/release/strata"

echo "== pytest bindings/python/tests (a worker per core)"
# Most tests hold the GIL (a Python BSDF plugin in Mitsuba's scalar variant):
# one process each core, the idle one stealing the slow renders' neighbours.
python -m pytest -q -n auto --dist worksteal bindings/python/tests
