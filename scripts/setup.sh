#!/usr/bin/env bash
# Installs what srug needs on Debian 12 and is missing: the Vulkan loader,
# lavapipe (mesa-vulkan-drivers, Mesa 25 from bookworm-backports unless SRUG_MESA=debian), the Khronos validation layer, and Debian's
# static shaderc/glslang/SPIRV-Tools libraries; gcc and python3 for the C API's
# tests (C programs under AddressSanitizer) and its ctypes example, python3-venv
# for the Python package's virtual environment (pip fetches maturin, numpy and
# pytest from PyPI); a TrueType
# font (fonts-dejavu-core) for the text of `srug bench trade`'s plot. Idempotent;
# needs root (or sudo) only when something is missing. Rust (cargo) must already be installed.
# Sourced (by scripts/test.sh and scripts/demo.sh, or in a developer's shell for its
# environment): the caller's shell options come back at the end, so a shell that sources
# it does not keep `-e` (which would end it at the first command that fails).
_srug_setup_restore=""
case $- in *e*) ;; *) _srug_setup_restore+="set +e;" ;; esac
case $- in *u*) ;; *) _srug_setup_restore+="set +u;" ;; esac
shopt -qo pipefail || _srug_setup_restore+="set +o pipefail;"
set -euo pipefail

packages=(
  libvulkan1 libvulkan-dev mesa-vulkan-drivers vulkan-validationlayers vulkan-tools
  libshaderc-dev glslang-dev spirv-tools pkg-config ca-certificates
  gcc libc6-dev python3 python3-venv fonts-dejavu-core
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "srug setup: installing ${missing[*]}" >&2
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# lavapipe: Debian 12 ships Mesa 22.3; bookworm-backports' Mesa 25 renders 1.2-1.4x faster
# (docs/bench/mesa.md), so it is the default there. SRUG_MESA=debian keeps Debian's own;
# scripts/mesa.sh runs either one without installing it. Other releases keep theirs.
srug_mesa="${SRUG_MESA:-backports}"
case "$srug_mesa" in
  backports | debian) ;;
  *) echo "srug setup: SRUG_MESA=$srug_mesa: is not backports or debian" >&2; exit 1 ;;
esac
if [ "$srug_mesa" = backports ] && grep -qs '^VERSION_CODENAME=bookworm' /etc/os-release; then
  have="$(dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null || true)"
  if ! dpkg --compare-versions "${have:-0}" ge 25; then
    keep="${have:-the Debian 12 one}"
    echo "srug setup: installing Mesa 25 (lavapipe) from bookworm-backports (SRUG_MESA=debian keeps $keep)" >&2
    SUDO=""
    if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
    export DEBIAN_FRONTEND=noninteractive
    if ! grep -rqs 'bookworm-backports' /etc/apt/sources.list /etc/apt/sources.list.d/; then
      printf '%s\n' 'Types: deb' 'URIs: http://deb.debian.org/debian' 'Suites: bookworm-backports' \
        'Components: main' 'Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg' |
        $SUDO tee /etc/apt/sources.list.d/srug-bookworm-backports.sources >/dev/null
    fi
    if ! { $SUDO apt-get update -qq &&
      $SUDO apt-get install -y -qq --no-install-recommends -t bookworm-backports mesa-vulkan-drivers >/dev/null; }; then
      echo "srug setup: warning: Mesa 25 from bookworm-backports could not be installed; keeping $keep" >&2
    fi
  fi
fi

if ! command -v cargo >/dev/null 2>&1; then
  for c in "$HOME/.cargo/bin/cargo" /usr/local/cargo/bin/cargo; do
    if [ -x "$c" ]; then export PATH="$(dirname "$c"):$PATH"; break; fi
  done
fi
if ! command -v cargo >/dev/null 2>&1; then
  echo "srug setup: cargo not found; install a Rust toolchain (1.85 or newer) first" >&2
  exit 1
fi
# The style checks of the test command need rustfmt and clippy.
if command -v rustup >/dev/null 2>&1; then
  for c in rustfmt clippy; do
    rustup component list --installed 2>/dev/null | grep -q "^$c" || rustup component add "$c" >&2
  done
fi
eval "$_srug_setup_restore"
unset _srug_setup_restore
