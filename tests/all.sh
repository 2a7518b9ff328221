#!/usr/bin/env bash
# The whole test suite, as the README gives it: the Rust workspace, then the
# Python package, built from source (maturin, from PyPI) into a virtual
# environment under target/ and tested with pytest. Needs Rust and
# Python >= 3.9 with venv and pip; PYTHON picks the interpreter.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test --workspace
venv=target/python-venv
if [ ! -x "$venv/bin/python" ]; then
  "${PYTHON:-python3}" -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check "./python[test]"
"$venv/bin/python" -m pytest -q python/tests
