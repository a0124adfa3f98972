#!/usr/bin/env bash
# Install hapticdesk with its test extras (and the example plugin) and run the whole test suite,
# the long soak cases (`-m slow`) included. A plain `pytest` leaves those out.
set -euo pipefail
cd "$(dirname "$0")/.."
python -m pip install -q -e '.[test]'
python -m pip install -q -e examples/plugin-example
# the estimator's kernels compiled once before the tests (30-45 s on a fresh clone): the tests
# that start a desk in a child process and wait for it would otherwise pay it inside their wait
python -c "from hapticdesk.estimator import kernel; kernel.warm()"
python -m pytest -q -m "slow or not slow" "$@"
# the example plugin package carries its own tests (and its own pytest settings)
(cd examples/plugin-example && python -m pytest -q)
