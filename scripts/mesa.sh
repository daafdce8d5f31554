#!/usr/bin/env bash
# Runs a command on the other lavapipe without installing it: Debian 12's Mesa 22.3
# ("debian") or bookworm-backports' Mesa 25 ("backports"), unpacked from its package into
# target/mesa/<which> with the libdrm it needs and its own Vulkan ICD file.
#
#   bash scripts/mesa.sh debian bash scripts/test.sh      # the suite on Mesa 22.3
#   bash scripts/mesa.sh backports target/release/srug bench splat
#   eval "$(bash scripts/mesa.sh debian)"                 # no command: prints the exports
#
# Needs apt's lists for the suite asked for (scripts/setup.sh adds bookworm-backports).
set -euo pipefail

which="${1:-}"
case "$which" in
  debian) suite=bookworm ;;
  backports) suite=bookworm-backports ;;
  *) echo "usage: scripts/mesa.sh debian|backports [COMMAND...]" >&2; exit 2 ;;
esac
shift

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
dir="$root/target/mesa/$which"
icd="$dir/lvp_icd.json"
if [ ! -f "$icd" ]; then
  rm -rf "$dir.tmp" && mkdir -p "$dir.tmp/debs"
  if ! (cd "$dir.tmp/debs" && apt-get download -qq "mesa-vulkan-drivers/$suite" "libdrm2/$suite" "libdrm-amdgpu1/$suite" >&2); then
    echo "scripts/mesa.sh: could not download mesa-vulkan-drivers from $suite (is it in apt's sources? scripts/setup.sh adds bookworm-backports)" >&2
    exit 1
  fi
  for deb in "$dir.tmp"/debs/*.deb; do dpkg -x "$deb" "$dir.tmp/root"; done
  lib="$dir/root/usr/lib/x86_64-linux-gnu"
  printf '{ "file_format_version": "1.0.0", "ICD": { "library_path": "%s", "api_version": "1.3.0" } }\n' \
    "$lib/libvulkan_lvp.so" >"$dir.tmp/lvp_icd.json"
  rm -rf "$dir" && mv "$dir.tmp" "$dir"
fi

export VK_DRIVER_FILES="$icd"
export LD_LIBRARY_PATH="$dir/root/usr/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
if [ "$#" -eq 0 ]; then
  printf 'export VK_DRIVER_FILES=%q\nexport LD_LIBRARY_PATH=%q\n' "$VK_DRIVER_FILES" "$LD_LIBRARY_PATH"
else
  exec "$@"
fi
