// Shared by scan_reduce.comp and scan_apply.comp: layout and push constants.
#ifndef SRUG_SCAN_COMMON_GLSL
#define SRUG_SCAN_COMMON_GLSL
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"

// Keep in sync with engine/src/primitives/scan.rs `ScanPush`.
layout(push_constant) uniform ScanPush {
    uvec2 data;  // uint[count], scanned in place
    uvec2 sums;  // uint[ceil(count / run)], one per invocation
    uint count;
    uint has_sums;  // scan_apply.comp: whether `sums` holds scanned offsets
    uint run;       // values per invocation (the level's run length)
    uint pad;
} pc;

#endif
