// Shared by the splatting kernels: the frame uniform and the per-splat record.
#ifndef SRUG_SPLAT_GLSL
#define SRUG_SPLAT_GLSL
#include "address.glsl"
#include "splat_types.glsl"

// Keep in sync with engine/src/splat/mod.rs `FrameUniform` (std140: vec4/uvec4 only).
layout(std140, set = 0, binding = 0) uniform Frame {
    vec4 rot0;         // world-to-camera rotation, rows
    vec4 rot1;
    vec4 rot2;
    vec4 translation;  // xyz: world-to-camera translation; w: 0 pinhole, 1 orthographic
    vec4 intrinsics;   // fx, fy, cx, cy (orthographic: pixels per unit x, y, cx, cy)
    vec4 clip;         // near, far, Jacobian limit x, y (tan of the half fov × 1.3)
    vec4 eye;          // camera centre
    vec4 view_dir;     // viewing direction (orthographic SH direction)
    vec4 background;   // rgb
    uvec4 size;        // width, height, tiles_x, tiles_y
    uvec4 counts;      // gaussians, SH degree stored | used << 8, normal_source (0 shortest axis, 1 stored), pairs
    uvec4 scene0;      // means, log_scales
    uvec4 scene1;      // rotations, opacity_logits
    uvec4 scene2;      // sh, normals
    uvec4 scene3;      // albedo, roughness
    uvec4 scene4;      // metallic, ao
    uvec4 scene5;      // visibility, splats
    uvec4 work0;       // features, tile_counts (offsets after the scan)
    uvec4 work1;       // keys, values
    uvec4 work2;       // ranges, rgb
    uvec4 out0;        // alpha, depth
    uvec4 out1;        // median_depth, normal
    uvec4 out2;        // albedo, roughness
    uvec4 out3;        // metallic, ao
    uvec4 out4;        // visibility, unused
} frame;

#endif
