#!/usr/bin/env bash
# On a lent GPU machine, from the repository root, with ./.device-bundle/bundle.tar.xz
# made by scripts/device/bundle.sh (carry .device-bundle): the C host programs
# (shared device, exported frames and semaphores, compositing over a rasterized
# mesh), then every test binary with the
# validation layer on, then benchmarks. Logs go to $OUT (or ./device-out).
# Test binaries find their sources through the paths they were built at, so
# the repository is linked there. TEST_LIMIT: seconds for all tests (300);
# TESTS: an extended regex picking test binaries by name (all); C_PROGRAMS=0 leaves
# the C programs out; BENCHES: which `srug bench` commands run after them (embed batch splat unet);
# COMMANDS: `srug` argument lists separated by `;`, run last, each into $OUT/commands.txt
# with its start and end times (e.g. COMMANDS='bench splat --sort-digits 4; bench splat
# --sort-digits block'); $OUT/clocks.csv logs the GPU's SM clock every 0.1 s (timestamps to
# match). At most 7 files land in $OUT: the device tool brings back 8.
set -u
root=$(pwd)
b=/tmp/srug-device
out=${OUT:-$root/device-out}
mkdir -p "$out" "$b" target/debug/deps
tar -C "$b" -xJf "$root/.device-bundle/bundle.tar.xz"
built_at=$(cat "$b/built_at")
if [ -n "$built_at" ] && [ ! -e "$built_at" ]; then mkdir -p "$(dirname "$built_at")" && ln -s "$root" "$built_at"; fi
cp "$b"/deps/* target/debug/deps/ && cp "$b/lib/libsrug_c.so" target/debug/deps/ && cp "$b/srug_debug" target/debug/srug
gl=$b/gl
# Where glvnd's own packages were carried (.gl, see docs/testing.md), install them as the
# machine's: some NVIDIA images' Vulkan driver does not come up over the bundle's copies.
if ls "$root"/.gl/*.deb > /dev/null 2>&1; then
  for f in "$root"/.gl/*.deb; do dpkg -x "$f" /; done
  ldconfig
  gl=
fi
export LD_LIBRARY_PATH=$b/lib${gl:+:$gl} VK_LAYER_PATH=$b/layers CPATH=$b/include LIBRARY_PATH=$b/lib
for icd in /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json /usr/share/vulkan/icd.d/nvidia_icd.json \
  /etc/vulkan/icd.d/nvidia_icd.json; do
  [ -f "$icd" ] && { export VK_DRIVER_FILES=$icd VK_ICD_FILENAMES=$icd; break; }
done
{ date; nvidia-smi -L 2>&1; echo "ICD: ${VK_DRIVER_FILES:-default}"; "$b/srug" devices ||
  { ls -l /dev/nvidia* 2>&1; VK_LOADER_DEBUG=error,warn,driver "$b/srug" devices; }; } > "$out/info.txt" 2>&1
# No Vulkan device: nothing below can run; stop before spending the lease.
"$b/srug" devices > /dev/null 2>&1 || { cat "$out/info.txt"; exit 1; }
sanitizers=(ASAN_OPTIONS=detect_leaks=1:halt_on_error=1:abort_on_error=0
  "LSAN_OPTIONS=suppressions=$root/bindings/tests/c/lsan.supp:print_suppressions=0"
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1)
[ "${C_PROGRAMS:-1}" = 0 ] || {
  for name in host export; do
    echo "== $name"; timeout 60 "$b/c/${name}_plain"; echo "rc=$?"
    echo "== $name (ASan)"; env "${sanitizers[@]}" timeout 90 "$b/c/${name}_asan"; echo "rc=$?"
  done
  echo "== composite"; timeout 60 "$b/c/composite_plain" /tmp/composite.ppm; echo "rc=$?"
  echo "== composite (ASan)"; env "${sanitizers[@]}" timeout 90 "$b/c/composite_asan" /tmp/composite.ppm; echo "rc=$?"
} > "$out/c_programs.txt" 2>&1
# The GPU's clocks, load and power every 0.1 s for the whole run: the SM clock falls to a
# fifth within seconds of the GPU idling (docs/bench/gpu.md, "The GPU's clock").
dmon=
if command -v nvidia-smi > /dev/null; then
  nvidia-smi --query-gpu=timestamp,clocks.sm,clocks.mem,utilization.gpu,power.draw,memory.used \
    --format=csv -lms 100 > "$out/clocks.csv" 2>&1 &
  dmon=$!
fi
export SRUG_VALIDATION=1
(cd target/debug/deps && ls "$b/deps" | grep -E "${TESTS:-.}" |
  timeout "${TEST_LIMIT:-300}" xargs -P4 -I{} sh -c 'timeout 240 ./{} --test-threads=4 > /tmp/srug_t_{}.log 2>&1; echo "{} rc=$?" >> /tmp/srug_rcs')
{ cat /tmp/srug_rcs; grep -h "^test result\|FAILED\|panicked" /tmp/srug_t_*.log; } > "$out/tests_summary.txt"
for f in /tmp/srug_t_*.log; do echo "######## $f"; cat "$f"; done > "$out/tests.log"
unset SRUG_VALIDATION
for bench in ${BENCHES-embed batch splat unet}; do
  { date +%T; echo "\$ srug bench $bench"; timeout 90 "$b/srug" bench "$bench"; echo "rc=$?"; date +%T; } >> "$out/benches.txt" 2>&1
done
IFS=';' read -ra commands <<< "${COMMANDS-}"
n=0
for c in "${commands[@]}"; do
  [ -n "${c// /}" ] || continue
  n=$((n + 1))
  # Word splitting of $c is the point: one srug argument list each.
  # shellcheck disable=SC2086
  { echo "######## command $n"; date +%T; echo "\$ srug ${c# }"; timeout 300 "$b/srug" $c; echo "rc=$?"; date +%T; } >> "$out/commands.txt" 2>&1
done
[ -z "$dmon" ] || kill "$dmon" 2> /dev/null
