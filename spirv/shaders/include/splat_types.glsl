// The per-splat record and typed buffer references, shared by the splatting
// kernels and the passes that walk a splatted frame again (shadow, backward).
#ifndef SRUG_SPLAT_TYPES_GLSL
#define SRUG_SPLAT_TYPES_GLSL
#include "address.glsl"

// One projected Gaussian, 64 bytes. Keep in sync with engine/src/splat/mod.rs `SPLAT_BYTES`.
struct Splat {
    vec4 head;      // mean (pixel coordinates, centres at +0.5), camera z (equirectangular: distance), opacity
    vec4 conic;     // inverse 2D covariance (a, b, c); w: surface-depth slope x (surface_slope.glsl), else 0
    vec4 color;     // rgb (0 where the frame blends no colour); w: surface-depth slope y, else 0
    uvec4 rect;     // tile rectangle [x0, y0, x1, y1) (x1 > tiles_x: wraps to the left edge)
};
layout(buffer_reference, std430, buffer_reference_align = 16) buffer Splats { Splat v[]; };
// Per-splat features: (normal.xyz, roughness), (albedo.rgb, metallic), (ao, visibility, 0, 0).
layout(buffer_reference, std430, buffer_reference_align = 16) buffer Features { vec4 v[]; };
// The same ten values at 16 bits in three uvec2 (24 bytes; forward-only frames,
// `SplatSettings::packed_features`; keep in sync with engine/src/splat/mod.rs
// `PACKED_FEATURE_BYTES` and the CPU twin `pack_features`):
// (snorm normal.xy, snorm normal.z | unorm roughness << 16),
// (unorm albedo.rg, unorm albedo.b | unorm metallic << 16), (unorm ao | unorm visibility << 16, 0).
layout(buffer_reference, std430, buffer_reference_align = 8) buffer PackedFeatures { uvec2 v[]; };

// The packed features of one splat (`Features`): the normal's components in [−1, 1], the rest in [0, 1].
void pack_features(vec3 n, float rough, vec3 albedo, float metal, float ao, float vis,
                   out uvec2 p0, out uvec2 p1, out uvec2 p2) {
    p0 = uvec2(packSnorm2x16(n.xy), (packSnorm2x16(vec2(n.z, 0.0)) & 0xffffu) | (packUnorm2x16(vec2(0.0, rough)) & 0xffff0000u));
    p1 = uvec2(packUnorm2x16(albedo.rg), packUnorm2x16(vec2(albedo.b, metal)));
    p2 = uvec2(packUnorm2x16(vec2(ao, vis)), 0u);
}

// `pack_features` undone: (normal.xyz, roughness), (albedo.rgb, metallic), (ao, visibility, 0, 0).
void unpack_features(uvec2 p0, uvec2 p1, uvec2 p2, out vec4 f0, out vec4 f1, out vec4 f2) {
    f0 = vec4(unpackSnorm2x16(p0.x), unpackSnorm2x16(p0.y).x, unpackUnorm2x16(p0.y).y);
    f1 = vec4(unpackUnorm2x16(p1.x), unpackUnorm2x16(p1.y));
    f2 = vec4(unpackUnorm2x16(p2.x), 0.0, 0.0);
}
layout(buffer_reference, std430, buffer_reference_align = 8) buffer Uvec2s { uvec2 v[]; };
layout(buffer_reference, std430, buffer_reference_align = 4) buffer Floats { float v[]; };


// The depth where a pixel's ray meets a splat's plane: centre depth z0,
// surface-depth slope (surface_slope.glsl), offset d = mean − centre. The
// blend and its backward both call this, so they agree bit for bit. CPU twin:
// engine/src/splat/cpu.rs `CpuSplat::depth_at`.
float plane_depth(float z0, vec2 slope, vec2 d, bool ortho) {
    float u = -dot(slope, d);
    return ortho ? z0 + u : z0 / (1.0 + u);
}

// α of a splat at `centre` as the blend computes it: min(0.99, o·exp(−σ));
// false where the blend skips the splat (σ < 0 or α < 1/255). The blend, its
// backward and the traced shadow pass all call this, so they agree bit for bit.
// `gauss` is exp(−σ) and `d` the centre's offset (mean − centre).
bool splat_alpha(vec4 head, vec4 conic, vec2 centre, out float alpha, out float gauss, out vec2 d) {
    d = head.xy - centre;
    float power = -0.5 * (conic.x * d.x * d.x + conic.z * d.y * d.y) - conic.y * d.x * d.y;
    gauss = exp(min(power, 0.0));
    alpha = min(0.99, head.w * gauss);
    return power <= 0.0 && alpha >= 1.0 / 255.0;
}

#endif
