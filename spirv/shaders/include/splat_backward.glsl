// Shared by the splat backward kernels: the backward uniform (binding 1; the
// forward frame's uniform stays at binding 0) and the per-pair record layout.
#ifndef SRUG_SPLAT_BACKWARD_GLSL
#define SRUG_SPLAT_BACKWARD_GLSL

// Which per-pixel gradients are given. Bits 0-7 as the blend's CHANNELS
// (depth, median depth, normal, albedo, roughness, metallic, ao, visibility),
// 256 rgb, 512 alpha. Keep in sync with engine/src/splat/backward.rs `BlendGrads::bits`.
layout(constant_id = 0) const uint GRADS = 0;
const bool GRAD_RGB = (GRADS & 256u) != 0u;
const bool GRAD_FEATURES = (GRADS & 252u) != 0u;
// Surface depths (the forward's SURFACE_DEPTH): each splat's depth at a pixel
// is where the pixel's ray meets its plane, so its gradient also reaches the
// splat's centre and its slope.
layout(constant_id = 2) const bool SURFACE_DEPTH = false;
// Floats per (tile, splat) record: mean.xy, conic.abc, opacity, depth, 0;
// then rgb + 0 with rgb; then the ten features + 0, 0 with any feature; then
// the slope's xy with surface depths. Keep in sync with
// engine/src/splat/backward.rs `record_stride`.
const uint SLOPE_AT = 8u + (GRAD_RGB ? 4u : 0u) + (GRAD_FEATURES ? 12u : 0u);
const uint STRIDE = SLOPE_AT + (SURFACE_DEPTH ? 2u : 0u);
const uint MAX_STRIDE = 26u;

// The splat's stored slope (splat_types.glsl: conic.w, colour.w).
vec2 stored_slope(vec4 conic, vec4 color) { return vec2(conic.w, color.w); }

// The splat's depth at offset d = mean − centre: its centre's, or with
// SURFACE_DEPTH where the ray meets its plane (`plane_depth`, as the blend's `splat_depth`).
float depth_at(float z0, vec2 slope, vec2 d, bool ortho) {
    return SURFACE_DEPTH ? plane_depth(z0, slope, d, ortho) : z0;
}

// Host mirror: engine/src/splat/backward.rs `BackwardUniform` (its layout is checked against this block).
// Addresses (low, high); 0 where a gradient is not given.
layout(std140, set = 0, binding = 1) uniform Backward {
    uvec2 d_rgb;             // per-pixel gradients in
    uvec2 d_alpha;
    uvec2 d_depth;
    uvec2 d_median_depth;
    uvec2 d_normal;
    uvec2 d_albedo;
    uvec2 d_roughness;
    uvec2 d_metallic;
    uvec2 d_ao;
    uvec2 d_visibility;
    uvec2 pairs;             // per-(tile, splat) records
    uvec2 unused0;
    uvec2 d_means;           // per-Gaussian gradients out
    uvec2 d_log_scales;
    uvec2 d_rotations;
    uvec2 d_opacity_logits;
    uvec2 d_values;          // 16 floats per Gaussian: rgb, 0, ten features, 0, 0
    uvec2 unused1;
} bwd;

#endif
