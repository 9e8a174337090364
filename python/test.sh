#!/usr/bin/env bash
# The Python package's tests: installs the package from this checkout into the virtual
# environment target/python-venv (a release build of crates/python in the workspace's target
# folder, so the crates `cargo test --release` compiled are reused) and runs pytest on
# python/tests, with the test extras (pytest, JAX, optax, PyTorch: the layers' tests skip
# without them, and fail under CI=true). Arguments go to pytest. Exit code 5 of pytest (no
# tests collected) fails.
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${LOAM_PYTHON_VENV:-target/python-venv}"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$PWD/target}"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check "./python[test]"
"$venv/bin/python" -m pytest python/tests "$@"
