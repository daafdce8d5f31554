#!/usr/bin/env bash
# The whole test suite: set up what is missing, check style (rustfmt, clippy
# with warnings as errors, rustdoc with warnings as errors), then run every test
# with the Khronos validation layer on (tests fail on any validation message),
# then build and install the Python package into a virtual environment and run its tests.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
export SRUG_VALIDATION=1
# lavapipe: use both cores for its rasterizer threads.
export LP_NUM_THREADS="${LP_NUM_THREADS:-2}"
cargo fmt --all --check
cargo clippy --locked --workspace --all-targets -- -D warnings
RUSTDOCFLAGS="-D warnings" cargo doc --locked --workspace --no-deps
cargo build --locked --workspace --all-targets
log=$(mktemp)
trap 'rm -f "$log"' EXIT
status=0
# --no-fail-fast: a failing test binary does not hide the others' results.
cargo test --locked --no-fail-fast --workspace --lib --bins --tests -- --test-threads=2 2>&1 | tee "$log" || status=$?
# The Python package: `pip install ./python` (maturin; the dev profile reuses the build above)
# into a virtual environment, then its pytest suite.
venv=target/python-venv
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
MATURIN_PEP517_ARGS="--profile dev" "$venv/bin/pip" install --quiet --disable-pip-version-check "./python[test]"
"$venv/bin/python" -m pytest python/tests -q -p no:cacheprovider 2>&1 | tee -a "$log" || status=$?
# One plain closing line with the totals over every test binary and the pytest run.
awk '/^test result:/ { for (i = 1; i <= NF; i++) { if ($(i+1) ~ /^passed/) p += $i; if ($(i+1) ~ /^failed/) f += $i } }
     / in [0-9.]+s/ && /(passed|failed)/ && !/^test result:/ {
       for (i = 1; i <= NF; i++) { if ($(i+1) ~ /^passed/) p += $i; if ($(i+1) ~ /^failed/) f += $i } }
     END { printf "srug tests: %d passed, %d failed\n", p, f }' "$log"
exit "$status"
