#!/usr/bin/env bash
# Packs what a lent GPU machine (bare: no Rust, no Vulkan loader, no validation layer,
# no shaderc) needs to run srug's test binaries and benchmarks: stripped test
# binaries, the CLI, the C test programs prebuilt (plain and under ASan/UBSan),
# the Vulkan loader, the Khronos validation layer, glvnd (NVIDIA's Vulkan driver
# loads through libGLX) and the Vulkan headers the C tests include, into one
# archive, ./.device-bundle/bundle.tar.xz (ignored by git; about 35 MB). Run here, after `source scripts/setup.sh`;
# then on the GPU machine, from the repository root: `bash scripts/device/run.sh`.
# See docs/testing.md, "On a GPU".
set -euo pipefail
cd "$(dirname "$0")/../.."
out=.device-bundle/stage
lib=/usr/lib/x86_64-linux-gnu
rm -rf "$out" && mkdir -p "$out"/{deps,lib,gl,layers,c,include/vulkan,include/vk_video}
# Test binaries name their sources by this absolute path (CARGO_MANIFEST_DIR).
pwd > "$out/built_at"
cargo build --locked --release -p srug-cli
cargo build --locked -p srug-bindings
cargo test --locked --no-run --workspace --lib --bins --tests 2>&1 | tee /dev/stderr |
  grep -o 'target/debug/deps/[^) ]*' | grep -v '/_srug-' | while read -r exe; do cp "$exe" "$out/deps/"; done
cp target/debug/srug "$out/srug_debug"
cp target/release/srug "$out/srug"
cp target/debug/deps/libsrug_c.so "$out/lib/"
strip "$out"/deps/* "$out"/srug_debug "$out"/srug "$out"/lib/libsrug_c.so
cp -L "$lib/libvulkan.so.1" "$lib/libasan.so.8" "$lib/libubsan.so.1" "$out/lib/"
cp "$lib/libVkLayer_khronos_validation.so" "$out/layers/"
strip "$out/layers/libVkLayer_khronos_validation.so"
sed 's#"library_path": *"[^"]*"#"library_path": "./libVkLayer_khronos_validation.so"#' \
  /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json > "$out/layers/VkLayer_khronos_validation.json"
for l in libGLdispatch.so.0 libGLX.so.0 libX11.so.6 libxcb.so.1 libXau.so.6 libXdmcp.so.6 libbsd.so.0 libmd.so.0; do
  cp -L "$lib/$l" "$out/gl/"
done
cp /usr/include/vulkan/*.h "$out/include/vulkan/"
cp /usr/include/vk_video/*.h "$out/include/vk_video/"
# The C host programs of bindings/tests/c_api.rs, built as that test builds them
# (the GPU machine has a C compiler but no shaderc for composite.c).
shaderc=(-lshaderc_combined -lglslang -lMachineIndependent -lOSDependent -lGenericCodeGen -lOGLCompiler
  -lSPIRV -lglslang-default-resource-limits -lSPIRV-Tools-opt -lSPIRV-Tools -lstdc++)
for name in host export composite; do
  for variant in plain asan; do
    sanitize=()
    [ "$variant" = asan ] && sanitize=(-fsanitize=address,undefined -fno-sanitize-recover=undefined)
    extra=()
    [ "$name" = composite ] && extra=("${shaderc[@]}")
    cc -std=c11 -Wall -Wextra -Werror -pedantic -g -O1 -fno-omit-frame-pointer "${sanitize[@]}" \
      -I bindings/include "bindings/tests/c/$name.c" -o "$out/c/${name}_$variant" -Ltarget/debug/deps \
      -lsrug_c -lpthread -lm -ldl -lvulkan "${extra[@]}"
  done
done
strip "$out"/c/*
tar -C "$out" -cf - . | xz -9 -T2 > .device-bundle/bundle.tar.xz
rm -rf "$out"
ls -l .device-bundle/bundle.tar.xz
