// Buffers reached by device address (buffer_reference), for data that may
// exceed maxStorageBufferRange (128 MiB on lavapipe). Addresses travel in
// push constants as uvec2 (low, high).
#ifndef SRUG_ADDRESS_GLSL
#define SRUG_ADDRESS_GLSL
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require

layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer FloatsIn { float v[]; };
layout(buffer_reference, std430, buffer_reference_align = 4) writeonly buffer FloatsOut { float v[]; };
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer UintsIn { uint v[]; };
layout(buffer_reference, std430, buffer_reference_align = 4) writeonly buffer UintsOut { uint v[]; };

layout(buffer_reference, std430, buffer_reference_align = 4) buffer Uints { uint v[]; };

// One float (or uint) at a 64-bit address. Indexing `v[i]` of a reference is limited to byte offsets
// below 4 GiB on some drivers (NVIDIA wrapped at i = 2^30 floats); buffers that may be larger
// compute addresses in 64 bits with `element_address` (needs shaderInt64).
#ifdef SRUG_ADDRESS_64
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer FloatIn { float v; };
layout(buffer_reference, std430, buffer_reference_align = 4) writeonly buffer FloatOut { float v; };
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer UintIn { uint v; };
layout(buffer_reference, std430, buffer_reference_align = 4) writeonly buffer UintOut { uint v; };
uint64_t element_address(uvec2 base, uint index, uint stride) {
    return packUint2x32(base) + uint64_t(index) * uint64_t(stride);
}
#endif
layout(buffer_reference, std430, buffer_reference_align = 8) readonly buffer Uvec2sIn { uvec2 v[]; };
layout(buffer_reference, std430, buffer_reference_align = 8) writeonly buffer Uvec2sOut { uvec2 v[]; };

// Pairs of 32-bit words written as one 64-bit word each (low word first, as a
// uvec2 lies in memory; needs shaderInt64, which srug requires): lavapipe
// stores a per-lane uvec2 as two scattered stores, a 64-bit word as one.
#ifdef SRUG_WORDS_64
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
layout(buffer_reference, std430, buffer_reference_align = 8) writeonly buffer Uint64sOut { uint64_t v[]; };
#endif

#endif
