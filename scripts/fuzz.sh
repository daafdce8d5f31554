#!/usr/bin/env bash
# Coverage-guided fuzzing of the loaders with cargo-fuzz (nightly Rust):
#   scripts/fuzz.sh [TARGET...]       FUZZ_SECONDS per target (default 600)
# Targets: ply cameras environment ktx2_chain safetensors png scenes camera_files (srug_tests::fuzz).
# Seeds come from srug's own writers; findings land in fuzz/artifacts/<target>/
# and replay with `cargo run -p srug-tests --example fuzz_replay TARGET FILE`.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --locked
cargo run -q -p srug-tests --example fuzz_seeds -- fuzz/corpus
# Files other tools wrote, where the shared data is present (small ones only: libFuzzer caps inputs).
data=../shared/data
if [ -d "$data" ]; then
  copy() { find "$data/$1" -maxdepth 1 -name "$2" -size -4096k -exec cp {} "fuzz/corpus/$3/" \; 2>/dev/null || true; }
  copy hdri '*.hdr' environment
  copy hdri '*.exr' environment
  copy ktx2 '*.ktx2' environment
  copy ktx2 '*.ktx2' ktx2_chain
  copy scenes '*.ply' ply
  copy scenes "*.ply" scenes
fi
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(ply cameras environment ktx2_chain safetensors png scenes camera_files)
for t in "${targets[@]}"; do
  cargo +nightly fuzz run --fuzz-dir fuzz "$t" "fuzz/corpus/$t" -- \
    -max_total_time="${FUZZ_SECONDS:-600}" -rss_limit_mb=4096 -print_final_stats=1
done
