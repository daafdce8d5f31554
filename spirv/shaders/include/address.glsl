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
layout(buffer_reference, std430, buffer_reference_align = 8) readonly buffer Uvec2sIn { uvec2 v[]; };
layout(buffer_reference, std430, buffer_reference_align = 8) writeonly buffer Uvec2sOut { uvec2 v[]; };

#endif
