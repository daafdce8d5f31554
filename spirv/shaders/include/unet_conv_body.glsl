// The body of unet_conv.comp, unet_conv_half.comp, unet_conv_texel.comp and
// unet_conv_texel_half.comp (see there).
#extension GL_EXT_control_flow_attributes : require
#ifdef TEXEL_INPUT
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#endif
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"
#include "unet_storage.glsl"

layout(constant_id = 0) const uint STRIDE = 1;
// 0: none, 1: ReLU, 2: leaky ReLU (slope 0.01).
layout(constant_id = 1) const uint ACT = 1;
// Output channels per invocation: 4 or 8 (a multiple of 4).
layout(constant_id = 2) const uint OCB = 8;
// Output pixels per invocation along x: 1 to 16. Each weight read feeds PX
// pixels and each input row segment is read once for all of them (see
// engine/src/indirect/mod.rs `pixel_block`, `vec4_pixel_block`).
layout(constant_id = 3) const uint PX = 1;

#ifdef TEXEL_INPUT
// The subgroup's size where its lanes fetch a channel's weight texels side
// by side and broadcast them (0: every lane fetches every texel): the
// weights are the same in every lane (the workgroup's output block), and
// where a texel fetch is a call (lavapipe from Mesa 25) this is
// 1/WEIGHT_LANES of the calls (engine/src/indirect/mod.rs `weight_lanes`).
layout(constant_id = 6) const uint WEIGHT_LANES = 0u;
#define WEIGHT_STEP max(WEIGHT_LANES, 1u)
#define WEIGHT_ROUNDS ((9u * Q + WEIGHT_STEP - 1u) / WEIGHT_STEP)
// The layer's weights, [oc/OCB][ic][9][OCB] as RGBA32F texels (every input
// channel: one pass): a vec4 texelFetch costs lavapipe a quarter of a vec4
// uniform-buffer load at an index it cannot prove uniform (32 scalar loads).
layout(set = 0, binding = 0) uniform textureBuffer weight_texels;
#define WEIGHTS(i) texelFetch(weight_texels, int(i))
#else
// Keep in sync with engine/src/indirect/mod.rs `CONV_UBO_FLOATS`.
layout(std140, set = 0, binding = 0) uniform Weights { vec4 wts[4096]; };
#define WEIGHTS(i) wts[i]
#endif
layout(std430, set = 0, binding = 1) readonly buffer Bias { vec4 bias[]; };
#ifdef TEXEL_INPUT
// The two inputs as texel-buffer views (fp32 or fp16 elements; the view's
// format widens): lavapipe gathers texelFetch as one vector operation.
layout(set = 0, binding = 2) uniform textureBuffer input_a;
layout(set = 0, binding = 3) uniform textureBuffer input_b;
// The input views hold four pixels per texel (RGBA32F/RGBA16F) and each row
// segment takes NT fetches instead of SPAN. Needs the input width and
// PX·STRIDE to be multiples of 4, so every segment starts one pixel before a
// texel boundary (engine/src/indirect/mod.rs `vec4_fits`).
layout(constant_id = 4) const bool VEC4 = false;
#endif

// Keep in sync with engine/src/indirect/mod.rs `ConvPush`.
layout(push_constant) uniform ConvPush {
    uvec2 a;        // first input, ca channels
    uvec2 b;        // second input, cb channels (skip)
    uvec2 o;        // output, oc channels
    uvec2 partial;  // fp32 partial sums between passes, oc channels
    uint ca;
    uint cb;
    uint oc;
    uint ic0;       // this pass's input channels [ic0, ic1)
    uint ic1;
    uint flags;     // 1: first pass (start from the bias), 2: last pass (activate)
    uvec2 in_size;  // width, height
    uvec2 out_size;
} pc;

// Adds input channel `ic` times its weights to the accumulators; FILL_ROW
// sets rows[ky][0 .. SPAN) to the channel's input row iy (ky, iy, row_in
// known). All fetches come first, then the multiply-adds pixel by pixel: on
// lavapipe every fetch is a call that clobbers every vector register, and
// with no call inside the multiply-add loop one pixel's accumulators stay in
// registers while each weight is a memory operand (the earlier order, a
// fetch between every few multiply-adds, loaded and stored an accumulator
// for each; README, U-Net benchmark). llvmpipe splits fma() into a multiply
// and an add; other devices fuse it.
#define ACCUMULATE_CHANNEL(FILL_ROW)                                               \
    {                                                                              \
        uint wbase = ((ob * chunk + (ic - pc.ic0)) * 9u) * Q;                      \
        vec4 wt[36]; /* [ky·3 + kx][q], Q ≤ 4 */                                   \
        LOAD_WEIGHTS                                                               \
        float rows[3][33]; /* SPAN ≤ 33: PX ≤ 16, STRIDE ≤ 2 */                  \
        [[unroll]] for (int ky = 0; ky < 3; ++ky) {                                \
            int iy = oy * int(STRIDE) + ky - 1;                                    \
            bool row_in = iy >= 0 && iy < h;                                       \
            FILL_ROW                                                               \
        }                                                                          \
        [[unroll]] for (uint x = 0u; x < PX; ++x) {                                \
            [[unroll]] for (uint k = 0u; k < 9u; ++k) {                            \
                float v = rows[k / 3u][x * STRIDE + k % 3u];                       \
                [[unroll]] for (uint q = 0u; q < Q; ++q) acc[x * Q + q] = fma(vec4(v), wt[k * Q + q], acc[x * Q + q]); \
            }                                                                      \
        }                                                                          \
    }

// The channel's 9·Q weight texels into wt: with WEIGHT_LANES each lane
// fetches its share and the subgroup broadcasts them.
#if defined(TEXEL_INPUT)
#define LOAD_WEIGHTS                                                               \
    if (WEIGHT_LANES > 0u) {                                                       \
        vec4 lane_wt[36];                                                          \
        [[unroll]] for (uint r = 0u; r < WEIGHT_ROUNDS; ++r) {                     \
            lane_wt[r] = WEIGHTS(wbase + min(r * WEIGHT_LANES + gl_SubgroupInvocationID, 9u * Q - 1u)); \
        }                                                                          \
        [[unroll]] for (uint t = 0u; t < 9u * Q; ++t) wt[t] = subgroupBroadcast(lane_wt[t / WEIGHT_STEP], t % WEIGHT_STEP); \
    } else {                                                                       \
        [[unroll]] for (uint t = 0u; t < 9u * Q; ++t) wt[t] = WEIGHTS(wbase + t);  \
    }
#else
#define LOAD_WEIGHTS [[unroll]] for (uint t = 0u; t < 9u * Q; ++t) wt[t] = WEIGHTS(wbase + t);
#endif

#ifdef TEXEL_INPUT
// One fetch per tap from an R32F/R16F view (BASE: the channel plane's first element).
#define FILL_SCALAR(VIEW, BASE)                                                    \
    [[unroll]] for (uint k = 0u; k < SPAN; ++k) {                                  \
        rows[ky][k] = tap_in[ky][k] ? texelFetch(VIEW, int(BASE) + tap_at[ky][k]).r : 0.0; \
    }
// NT fetches per row from an RGBA32F/RGBA16F view of the same memory, four
// pixels each (BASE4: the plane's first texel); column ix0 = 4m − 1 is the
// last component of the row's first texel.
#define FILL_VEC4(VIEW, BASE4)                                                     \
    {                                                                              \
        vec4 seg[9];                                                               \
        [[unroll]] for (uint t = 0u; t < NT; ++t) seg[t] = texelFetch(VIEW, int(BASE4) + tex_at[ky][t]); \
        [[unroll]] for (uint k = 0u; k < SPAN; ++k) rows[ky][k] = tap_in[ky][k] ? seg[(k + 3u) / 4u][(k + 3u) % 4u] : 0.0; \
    }
#define FILL(VIEW, BASE)                                                           \
    if (VEC4) FILL_VEC4(VIEW, (BASE) / 4u) else { FILL_SCALAR(VIEW, BASE) }
#endif

void main() {
    uint plane = pc.out_size.x * pc.out_size.y;
    uint blocks_x = (pc.out_size.x + PX - 1u) / PX;
    uint p = (gl_WorkGroupID.y + gl_WorkGroupID.z * gl_NumWorkGroups.y) * WORKGROUP_SIZE_X + gl_LocalInvocationID.x;
    uint ob = gl_WorkGroupID.x;
    bool live = p < blocks_x * pc.out_size.y;
    p = min(p, blocks_x * pc.out_size.y - 1u);
    int ox0 = int((p % blocks_x) * PX), oy = int(p / blocks_x);
    int ow = int(pc.out_size.x);
    const uint Q = OCB / 4u;
    // acc[x * Q + q]: pixel ox0 + x, channels ob·OCB + 4q .. + 3 (PX·OCB ≤ 128).
    // Every loop over acc is unrolled: a dynamic index puts it in scratch memory, and with 64
    // accumulators that kept llvmpipe's compiler busy for over ten minutes.
    vec4 acc[32];
    [[unroll]] for (uint x = 0u; x < PX; ++x) {
        // Pixels past the row's end (a partial block) compute a clamped copy and are not stored.
        uint px = uint(oy * ow + min(ox0 + int(x), ow - 1));
        if ((pc.flags & 1u) != 0u) {
            [[unroll]] for (uint q = 0u; q < Q; ++q) acc[x * Q + q] = bias[Q * ob + q];
        } else {
            FloatsIn prev = FloatsIn(pc.partial);
            [[unroll]] for (uint q = 0u; q < Q; ++q) {
                [[unroll]] for (uint j = 0u; j < 4u; ++j) {
                    uint c = min(ob * OCB + 4u * q + j, pc.oc - 1u);
                    acc[x * Q + q][j] = prev.v[c * plane + px];
                }
            }
        }
    }
    uint in_plane = pc.in_size.x * pc.in_size.y;
    int w = int(pc.in_size.x), h = int(pc.in_size.y);
    // Input columns the block reads: ox0·S − 1 .. (ox0 + PX − 1)·S + 1.
    const uint SPAN = (PX - 1u) * STRIDE + 3u;
    int ix0 = ox0 * int(STRIDE) - 1;
    // Input channels per pass as packed (engine/src/indirect/mod.rs `pass_channels`).
#ifdef TEXEL_INPUT
    uint chunk = pc.ca + pc.cb;
#else
    uint chunk = 16384u / (gl_NumWorkGroups.x * OCB * 9u);
#endif
#ifdef TEXEL_INPUT
    // Each tap's element offset within a channel plane (clamped into the
    // image, so every fetch is in range) and whether it lies inside (else the
    // tap reads the zero padding): the same for every input channel.
    int tap_at[3][33];
    bool tap_in[3][33];
    // VEC4: the texels of each row segment, offsets within a plane (clamped into it).
    const uint NT = ((PX - 1u) * STRIDE + 5u) / 4u + 1u;
    int tex_at[3][9];
    int m = ox0 * int(STRIDE) / 4;
    int plane_texels = int(in_plane / 4u);
    for (int ky = 0; ky < 3; ++ky) {
        int iy = oy * int(STRIDE) + ky - 1;
        for (uint k = 0u; k < SPAN; ++k) {
            int ix = ix0 + int(k);
            tap_at[ky][k] = clamp(iy, 0, h - 1) * w + clamp(ix, 0, w - 1);
            tap_in[ky][k] = iy >= 0 && iy < h && ix >= 0 && ix < w;
        }
        for (uint t = 0u; t < NT; ++t) {
            tex_at[ky][t] = clamp(clamp(iy, 0, h - 1) * (w / 4) + m - 1 + int(t), 0, plane_texels - 1);
        }
    }
#endif
#ifdef TEXEL_INPUT
    // Input channels of A, then of B: each loop reads one view (a branch
    // between the two would make lavapipe fetch from both).
    for (uint ic = pc.ic0; ic < min(pc.ic1, pc.ca); ++ic) {
        uint base = ic * in_plane;
        ACCUMULATE_CHANNEL(FILL(input_a, base))
    }
    for (uint ic = max(pc.ic0, pc.ca); ic < pc.ic1; ++ic) {
        uint base = (ic - pc.ca) * in_plane;
        ACCUMULATE_CHANNEL(FILL(input_b, base))
    }
#else
    for (uint ic = pc.ic0; ic < pc.ic1; ++ic) {
        uvec2 src = ic < pc.ca ? pc.a : pc.b;
        uint base = (ic < pc.ca ? ic : ic - pc.ca) * in_plane;
        ACCUMULATE_CHANNEL([[unroll]] for (uint k = 0u; k < SPAN; ++k) {
            int ix = ix0 + int(k);
            rows[ky][k] = row_in && ix >= 0 && ix < w ? load_input(src, base + uint(iy * w + ix)) : 0.0;
        })
    }
#endif
    if (!live) return;
    bool last = (pc.flags & 2u) != 0u;
    [[unroll]] for (uint x = 0u; x < PX; ++x) {
        int ox = ox0 + int(x);
        uint px = uint(oy * ow + ox);
        [[unroll]] for (uint q = 0u; q < Q; ++q) {
            vec4 a = acc[x * Q + q];
            if (last) {
                if (ACT == 1u) {
                    a = max(a, 0.0);
                } else if (ACT == 2u) {
                    a = mix(a * 0.01, a, greaterThanEqual(a, vec4(0.0)));
                }
            }
            [[unroll]] for (uint j = 0u; j < 4u; ++j) {
                uint c = ob * OCB + 4u * q + j;
                if (all(bvec2(ox < ow, c < pc.oc))) {
                    if (last) {
                        store_output(pc.o, c * plane + px, a[j]);
                    } else {
                        FloatsOut(pc.partial).v[c * plane + px] = a[j];
                    }
                }
            }
        }
    }
}
