#version 460
// splat_blend.comp reading splats through texel-buffer views instead of
// device addresses: every lane fetches the tile's next sorted index (binding
// 3, R32UI) and that splat's position and conic (binding 1, RGBA32F, 4
// texels per splat) itself, with no election or broadcast; contributing
// lanes fetch colour and features (bindings 1 and 2). On lavapipe each fetch
// is one vector gather, where a device-address load is a loop over the
// lanes. Used where the splats and pairs fit maxTexelBufferElements.
// CPU twin: engine/src/splat/cpu.rs `render_cpu`.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#define SUBGROUP_LOADS
#define TEXEL_SPLATS
#include "splat_blend_body.glsl"
