#version 460
// splat_blend.comp (one load per subgroup for each splat's position and
// conic) reading each contribution's colour and features through
// texel-buffer views (bindings 1 and 2, RGBA32F) instead of device
// addresses. Used where the splats fit maxTexelBufferElements.
// CPU twin: engine/src/splat/cpu.rs `render_cpu`.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#define SUBGROUP_LOADS
#define TEXEL_SPLATS
#include "splat_blend_body.glsl"
