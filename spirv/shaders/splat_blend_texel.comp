#version 460
// splat_blend.comp reading splats through texel-buffer views instead of
// device addresses: every lane fetches the tile's next sorted index (binding
// 3, R32UI) and that splat's position and conic (binding 1, RGBA32F, 4
// texels per splat) itself, so no election or broadcast is needed; colour
// and features come the same way (bindings 1 and 2). On lavapipe each fetch
// is one vector gather, where a device-address load is a loop over the
// lanes. Replaces the subgroup-load
// blend where the splats and pairs fit maxTexelBufferElements. Each invocation
// blends PIXELS pixels (constant_id 2) of its tile row, so one set of fetches
// serves them all (at TILE / 2, a lane shades half a row and a subgroup one
// half of the tile). With ROW_MASKS (constant_id 6) a subgroup first reads
// only the pairs' key words, one per lane, and skips the splats that reach
// none of its blocks (half-tile columns × row pairs; most of a tile's list
// where splats are small against it): a ballot over each window of keys
// names the wanted ones, so skipped splats cost a share of one fetch, not
// four and the pixel arithmetic. With PIXEL_REACH (constant_id 7) a lane
// evaluates a splat only at the pixels of its row the splat can reach. With
// WINDOW_FETCH (constant_id 9) each lane instead fetches one wanted splat of
// the key window and the subgroup hands them out one at a time (a shuffle
// from the lane that holds each): one fetch
// per window, not per splat, where a fetch is a function call.
// CPU twin: engine/src/splat/cpu.rs `render_cpu`.
#extension GL_EXT_control_flow_attributes : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_shuffle : require
#define TEXEL_SPLATS
#include "splat_blend_body.glsl"
