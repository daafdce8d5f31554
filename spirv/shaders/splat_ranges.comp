#version 460
// Splatting stage 4, the sorted keys read by device address (see
// include/splat_ranges_body.glsl). Checked through the splat tests, whose
// images and pair lists the CPU twin (engine/src/splat/cpu.rs) gives.
#include "splat_ranges_body.glsl"
