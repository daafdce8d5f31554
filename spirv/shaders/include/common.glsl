// Shared helpers for every srug kernel. Include after #version and after
// `#define WORKGROUP_SIZE_X n`; common.glsl declares the local size from it.
// Per-tile kernels `#define TILE_WORKGROUP` instead: one workgroup per
// TILE×TILE tile, TILE (constant_id 16) invocations down and, across, TILE
// (constant_id 15) or TILE / pixels per invocation for kernels that shade
// several pixels each (splat_blend_texel.comp); keep in sync with
// engine/src/splat/mod.rs `TILE_SPEC_IDS`.
// (gl_WorkGroupSize read before the layout declaration is (1,1,1) in GLSL,
// which once silently broke 2D grids; a macro cannot be read too early.)
#ifndef SRUG_COMMON_GLSL
#define SRUG_COMMON_GLSL
// Texel buffers are declared `textureBuffer` and read with texelFetch without
// a sampler: a `samplerBuffer` would be an OpTypeSampledImage of Dim Buffer,
// which the SPIR-V validator (in the validation layer) warns about.
#extension GL_EXT_samplerless_texture_functions : require

#if defined(TILE_WORKGROUP)
layout(local_size_x = 16, local_size_y = 16, local_size_x_id = 15, local_size_y_id = 16) in;
const uint TILE = gl_WorkGroupSize.y;
const uint TILE_PIXELS = TILE * TILE;
#elif defined(WORKGROUP_SIZE_X)
layout(local_size_x = WORKGROUP_SIZE_X) in;
#else
#error "define WORKGROUP_SIZE_X or TILE_WORKGROUP before including common.glsl"
#endif

// Whole numbers in [0, 2^23) between float and uint, exactly, in two vector
// instructions: 2^23 + x has x in its mantissa bits. AVX2 has no unsigned
// conversions, so lavapipe's float(uint) and uint(float) are several
// instructions a lane (uint(float) a branch a lane); spirv-opt folds
// uint(int(x)) back into uint(x).
uint whole_to_uint(float x) { return floatBitsToUint(x + 8388608.0) - 0x4B000000u; }
uvec2 whole_to_uint(vec2 x) { return floatBitsToUint(x + 8388608.0) - 0x4B000000u; }
uvec4 whole_to_uint(vec4 x) { return floatBitsToUint(x + 8388608.0) - 0x4B000000u; }
float uint_to_whole(uint u) { return uintBitsToFloat(u | 0x4B000000u) - 8388608.0; }
vec4 uint_to_whole(uvec4 u) { return uintBitsToFloat(u | 0x4B000000u) - 8388608.0; }

// 1D work is dispatched as a 2D grid so counts above 65535 workgroups fit;
// the host side is `Recording::dispatch_1d` (keep in sync).
#ifdef WORKGROUP_SIZE_X
uint linear_index() {
    return gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * WORKGROUP_SIZE_X;
}
#endif

// Workgroup index in a 2D grid of workgroups (see linear_index).
uint block_index() {
    return gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
}

#endif
