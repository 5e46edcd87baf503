#!/usr/bin/env bash
# The README's two commands as a new user runs them: a fresh clone of REPO (default: this script's
# repository, its committed state) into a new folder and virtual environment, then the Quick start's
# first command (install, fit the shipped log), then its second (install with the test extras, the
# default suite) twice: the first run compiles the bytecode and numba's kernels, the second reads
# them. Prints each command's wall time and exit status.
#
#   bash scripts/check_fresh_clone.sh [REPO] 2>&1 | tee fresh.log
#
# Bytecode is cached as on a user's machine (PYTHONDONTWRITEBYTECODE unset). Needs network access
# or a wheel cache for pip, and ~1 GB in /tmp; removes nothing it did not create.
set -u
REPO=${1:-$(cd "$(dirname "$0")/.." && pwd)}
unset PYTHONDONTWRITEBYTECODE
WORK=$(mktemp -d /tmp/fresh_clone.XXXXXX)
git clone -q "$REPO" "$WORK/repo" || exit 2
cd "$WORK/repo" || exit 2
python -m venv "$WORK/venv" || exit 2
# shellcheck disable=SC1091
. "$WORK/venv/bin/activate"
run() {  # run NAME command...: wall time and exit status
    local name=$1
    shift
    local t0 rc
    t0=$(date +%s.%N)
    "$@"
    rc=$?
    printf '%s: %.1f s, exit %d\n' "$name" "$(echo "$(date +%s.%N) - $t0" | bc)" "$rc"
}
run "first command (install, quick-start fit)" bash -c 'pip install -q . && bayes-imu fit data_synthetic/gyro_lowgrade.csv.gz --column gyro_x_dps --rate 100 --units deg/s --out quickstart > /dev/null'
run "second command, first run (install with test extras, suite)" bash -c 'pip install -q -e ".[test]" && python -m pytest -q 2>&1 | tail -2'
run "the suite again (bytecode and kernels cached)" bash -c 'python -m pytest -q 2>&1 | tail -2'
echo "work folder: $WORK (remove when done)"
