#!/usr/bin/env bash
# The whole test suite: set up what is missing, then run every test with the
# Khronos validation layer on (tests fail on any validation message).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
export SRUG_VALIDATION=1
# lavapipe: use both cores for the rasterizer threads.
export LP_NUM_THREADS="${LP_NUM_THREADS:-2}"
cargo build --locked --workspace --all-targets
cargo test --locked --workspace -- --test-threads=2
