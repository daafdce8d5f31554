// The body of unet_upsample.comp, unet_upsample_half.comp, unet_upsample_texel.comp
// and unet_upsample_texel_half.comp (see there).
#extension GL_EXT_control_flow_attributes : require
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"
#include "unet_storage.glsl"

// Keep in sync with engine/src/indirect/mod.rs `UpsamplePush`.
layout(push_constant) uniform UpsamplePush {
    uvec2 src;
    uvec2 dst;
    uvec2 in_size;
    uvec2 out_size;
    uint channels;
    uint align_corners;
} pc;

#ifdef TEXEL_INPUT
// The source as a texel-buffer view (R32F or R16F), gathered as one vector op on lavapipe.
layout(set = 0, binding = 0) uniform textureBuffer src;
#define LOAD(i) texelFetch(src, int(i)).r
#else
#define LOAD(i) load_input(pc.src, i)
#endif

// Source coordinate and its two neighbours along one axis (PyTorch's rule).
void source(uint d, uint n_in, uint n_out, out uint i0, out uint i1, out float t) {
    float s;
    if (pc.align_corners != 0u) {
        s = n_out > 1u ? float(d) * float(n_in - 1u) / float(n_out - 1u) : 0.0;
    } else {
        s = max((float(d) + 0.5) * float(n_in) / float(n_out) - 0.5, 0.0);
    }
    i0 = min(uint(s), n_in - 1u);
    i1 = min(i0 + 1u, n_in - 1u);
    t = s - float(i0);
}

// Output pixels per invocation along x: 4 (FOUR, where the output width is a
// multiple of 4: one 16-byte store instead of four lane-by-lane scalar ones
// on lavapipe, and the row's source rows and weights computed once) or 1.
layout(constant_id = 0) const bool FOUR = false;

#ifdef TEXEL_INPUT
// Exactly twice the source size in both axes with align_corners false, the
// source width a multiple of 4 and viewed four pixels per texel (RGBA32F or
// RGBA16F): output pixel 2i is ¼ of source i − 1 and ¾ of i, pixel 2i + 1 ¾
// of i and ¼ of i + 1 (neighbours clamped to the edge, which is PyTorch's
// rule there too). An invocation takes four source pixels of one row and
// writes the 8 × 2 output pixels they centre, from 9 four-pixel fetches: no
// per-pixel gather (a slow `vpgatherdd` on lavapipe) and no coordinate maths.
layout(constant_id = 1) const bool EXACT2 = false;

// Source row `row` (a texel index of its first four pixels), four pixels from
// texel k: (left neighbour, the four, right neighbour), clamped to the row.
void six(uint row, uint k, uint last, out float l, out vec4 c, out float r) {
    c = texelFetch(src, int(row + k));
    l = k > 0u ? texelFetch(src, int(row + k - 1u)).w : c.x;
    r = k < last ? texelFetch(src, int(row + k + 1u)).x : c.w;
}

// Stores one output row's 8 pixels from the (vertically blended) six source values.
void store_row(uint at, float l, vec4 c, float r) {
    vec4 even = mix(c, vec4(l, c.xyz), 0.25);
    vec4 odd = mix(c, vec4(c.yzw, r), 0.25);
    store_output4(pc.dst, at, vec4(even.x, odd.x, even.y, odd.y));
    store_output4(pc.dst, at + 4u, vec4(even.z, odd.z, even.w, odd.w));
}

void exact2() {
    uint k = gl_GlobalInvocationID.x, j = gl_WorkGroupID.y, c = gl_WorkGroupID.z;
    uint quads = pc.in_size.x / 4u;
    if (k >= quads || j >= pc.in_size.y || c >= pc.channels) return;
    uint plane = c * pc.in_size.y;
    float lu, l0, ld, ru, r0, rd;
    vec4 cu, c0, cd;
    six((plane + (j > 0u ? j - 1u : 0u)) * quads, k, quads - 1u, lu, cu, ru);
    six((plane + j) * quads, k, quads - 1u, l0, c0, r0);
    six((plane + min(j + 1u, pc.in_size.y - 1u)) * quads, k, quads - 1u, ld, cd, rd);
    uint at = ((c * pc.out_size.y + 2u * j) * pc.out_size.x) + 8u * k;
    store_row(at, mix(l0, lu, 0.25), mix(c0, cu, 0.25), mix(r0, ru, 0.25));
    store_row(at + pc.out_size.x, mix(l0, ld, 0.25), mix(c0, cd, 0.25), mix(r0, rd, 0.25));
}
#endif

// One invocation per FOUR ? 4 : 1 output pixels: x along the workgroup, y and
// the channel from the grid (no integer division per pixel: on lavapipe a
// vector integer division runs lane by lane).
void main() {
#ifdef TEXEL_INPUT
    if (EXACT2) {
        exact2();
        return;
    }
#endif
    const uint N = FOUR ? 4u : 1u;
    uint ox0 = gl_GlobalInvocationID.x * N, oy = gl_WorkGroupID.y, c = gl_WorkGroupID.z;
    if (ox0 >= pc.out_size.x || oy >= pc.out_size.y || c >= pc.channels) return;
    uint y0, y1;
    float ty;
    source(oy, pc.in_size.y, pc.out_size.y, y0, y1, ty);
    uint base = c * pc.in_size.x * pc.in_size.y;
    uint row0 = base + y0 * pc.in_size.x, row1 = base + y1 * pc.in_size.x;
    vec4 out4;
    [[unroll]] for (uint k = 0u; k < N; ++k) {
        uint x0, x1;
        float tx;
        source(ox0 + k, pc.in_size.x, pc.out_size.x, x0, x1, tx);
        float top = mix(LOAD(row0 + x0), LOAD(row0 + x1), tx);
        float bottom = mix(LOAD(row1 + x0), LOAD(row1 + x1), tx);
        out4[k] = mix(top, bottom, ty);
    }
    uint at = (c * pc.out_size.y + oy) * pc.out_size.x + ox0;
    if (FOUR) {
        store_output4(pc.dst, at, out4);
    } else {
        store_output(pc.dst, at, out4.x);
    }
}
