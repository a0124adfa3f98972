#!/usr/bin/env bash
# Install hapticdesk with its test extras (and the example plugin) and run the test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
python -m pip install -q -e '.[test]'
if [ -d examples/plugin-example ]; then python -m pip install -q -e examples/plugin-example; fi
python -m pytest -q "$@"
