// The body of unet_upsample.comp, unet_upsample_half.comp, unet_upsample_texel.comp
// and unet_upsample_texel_half.comp (see there).
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"
#include "unet_storage.glsl"

// Keep in sync with engine/src/indirect/mod.rs `UpsamplePush`.
layout(push_constant) uniform Push {
    uvec2 src;
    uvec2 dst;
    uvec2 in_size;
    uvec2 out_size;
    uint channels;
    uint align_corners;
} pc;

#ifdef TEXEL_INPUT
// The source as a texel-buffer view (R32F or R16F), gathered as one vector op on lavapipe.
layout(set = 0, binding = 0) uniform samplerBuffer src;
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

// One invocation per output pixel: x along the workgroup, y and the channel
// from the grid (no integer division per pixel: on lavapipe a vector integer
// division runs lane by lane).
void main() {
    uint ox = gl_GlobalInvocationID.x, oy = gl_WorkGroupID.y, c = gl_WorkGroupID.z;
    if (ox >= pc.out_size.x || oy >= pc.out_size.y || c >= pc.channels) return;
    uint x0, x1, y0, y1;
    float tx, ty;
    source(ox, pc.in_size.x, pc.out_size.x, x0, x1, tx);
    source(oy, pc.in_size.y, pc.out_size.y, y0, y1, ty);
    uint base = c * pc.in_size.x * pc.in_size.y;
    float top = mix(LOAD(base + y0 * pc.in_size.x + x0), LOAD(base + y0 * pc.in_size.x + x1), tx);
    float bottom = mix(LOAD(base + y1 * pc.in_size.x + x0), LOAD(base + y1 * pc.in_size.x + x1), tx);
    store_output(pc.dst, (c * pc.out_size.y + oy) * pc.out_size.x + ox, mix(top, bottom, ty));
}
