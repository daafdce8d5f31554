#!/usr/bin/env bash
# Regenerates tests/data/formats: the fixture scene written by srug as PLY,
# then converted by other tools (PlayCanvas splat-transform, which bundles
# Niantic's SPZ reference as WASM) into every format they write, and each
# decoded back to PLY by the same tool (the reference decodes the tests
# compare srug's readers with). Needs node and npm; run from the repository root.
set -euo pipefail
out=tests/data/formats
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$out"
cargo run -q -p srug-tests --example format_source -- "$out/source.ply"
npm install --silent --prefix "$work" @playcanvas/splat-transform@2.7.1 >/dev/null
st() { node "$work/node_modules/@playcanvas/splat-transform/bin/cli.mjs" -w -q "$@"; }
st "$out/source.ply" "$out/st.compressed.ply"
st "$out/source.ply" "$out/st.v4.spz"
st --spz-version 3 "$out/source.ply" "$out/st.v3.spz"
st -g cpu "$out/source.ply" "$out/st.sog"
st "$out/source.ply" "$out/st.glb"
# Version 2 SPZ straight from the reference's own packer (splat-transform writes 3 and 4).
cat > "$work/v2.mjs" <<'JS'
import fs from 'node:fs';
import createModule from '@adobe/spz';
const spz = await createModule();
const cloud = spz.loadSpzFromBuffer(new Uint8Array(fs.readFileSync(process.argv[2])), { to: spz.CoordinateSystem.RUB });
const bytes = spz.saveSpzToBuffer(cloud, { version: 2, from: spz.CoordinateSystem.RUB, sh1Bits: 5, shRestBits: 4 });
fs.writeFileSync(process.argv[3], bytes);
JS
(cd "$work" && node v2.mjs "$OLDPWD/$out/st.v3.spz" "$OLDPWD/$out/st.v2.spz")
# srug's own writers, decoded by splat-transform (it reads .splat but does not write it).
for f in srug.splat srug.spz srug.compressed.ply srug.sog; do
    cargo run -q -p srug-cli -- convert "$out/source.ply" "$out/$f"
done
for f in st.compressed.ply st.v4.spz st.v3.spz st.v2.spz st.sog srug.splat srug.spz srug.compressed.ply srug.sog; do
    st "$out/$f" "$out/$f.decoded.ply"
done
ls -l "$out"
