// The per-splat record and typed buffer references, shared by the splatting
// kernels and the passes that walk a splatted frame again (shadow, backward).
#ifndef SRUG_SPLAT_TYPES_GLSL
#define SRUG_SPLAT_TYPES_GLSL
#include "address.glsl"

#define TILE 16

// One projected Gaussian, 64 bytes. Keep in sync with engine/src/splat/mod.rs `SPLAT_BYTES`.
struct Splat {
    vec4 head;      // mean (pixel coordinates, centres at +0.5), camera z, opacity
    vec4 conic;     // inverse 2D covariance (a, b, c), radius
    vec4 color;     // rgb, unused
    uvec4 rect;     // tile rectangle [x0, y0, x1, y1)
};
layout(buffer_reference, std430, buffer_reference_align = 16) buffer Splats { Splat v[]; };
// Per-splat features: (normal.xyz, roughness), (albedo.rgb, metallic), (ao, visibility, 0, 0).
layout(buffer_reference, std430, buffer_reference_align = 16) buffer Features { vec4 v[]; };
layout(buffer_reference, std430, buffer_reference_align = 8) buffer Uvec2s { uvec2 v[]; };
layout(buffer_reference, std430, buffer_reference_align = 4) buffer Floats { float v[]; };

#endif
