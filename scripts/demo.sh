#!/usr/bin/env bash
# The main job: set up what is missing, build, and run `srug demo`.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
cargo build --release --locked -p srug-cli
exec target/release/srug demo "$@"
