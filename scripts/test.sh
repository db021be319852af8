#!/usr/bin/env bash
# The test command (README quick start, step 2; .ci/run calls it): installs Debian's mosquitto when
# it is missing (the MQTT bus tests run against a real broker) and Debian's chromium (the web map's
# browser test drives it through Playwright, which downloads no browser), the package with its test extras,
# then the static checks (ruff, then mypy with its pyproject config; its cache .mypy_cache keeps a
# rerun fast), then pytest. Either check failing fails the script before any test runs. Extra
# arguments go to pytest, e.g. scripts/test.sh tests/bus/test_bus.py. The tests run on two pytest-xdist
# workers (most of a test's time is a simulated flight waiting on its clock); the firmware tests are
# one group flown by one worker in turn (tests/conftest.py). `-rs` names every skipped test and its reason.
set -euo pipefail
cd "$(dirname "$0")/.."
SUDO=""
if [ "$(id -u)" != 0 ] && command -v sudo >/dev/null; then SUDO="sudo"; fi
MISSING=""
if ! command -v mosquitto >/dev/null && [ ! -x /usr/sbin/mosquitto ]; then MISSING="mosquitto"; fi
if ! command -v chromium >/dev/null; then MISSING="$MISSING chromium"; fi
if [ -n "$MISSING" ]; then
    # shellcheck disable=SC2086  # one word per package
    $SUDO apt-get update && $SUDO apt-get install -y $MISSING
fi
python3 -m pip install -q -e '.[test]'
python3 -m ruff check .
python3 -m mypy
python3 -m pytest -q -rs -n 2 --dist loadgroup --durations=15 "$@"
