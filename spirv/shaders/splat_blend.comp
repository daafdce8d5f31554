#version 460
// Splatting stage 5: one workgroup per tile (16×16 by default), one invocation per pixel,
// front-to-back alpha blending over the tile's sorted splats. A pixel stops
// once T·(1−α) < 1e-4 (that splat excluded); the workgroup ends when all its
// pixels have. Reads splats from global memory (no shared-memory batches:
// on lavapipe barriers cost more than they save). CHANNELS picks what else is
// blended besides rgb and alpha, so unrequested channels cost nothing.
// Blended channels other than rgb are Σ wᵢ xᵢ with wᵢ = αᵢ Tᵢ (premultiplied
// by alpha); median depth is the depth where T first falls to MEDIAN_T (0.5 unless asked) or below.
// CPU twin: engine/src/splat/cpu.rs `render_cpu`.
// This variant loads each splat once per subgroup (needs subgroup ballot);
// splat_blend_portable.comp loads per invocation, for devices without it.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#define SUBGROUP_LOADS
#include "splat_blend_body.glsl"
