// Body of splat_blend.comp and splat_blend_portable.comp (see their headers).
#define WORKGROUP_SIZE_X 256
#include "common.glsl"
#include "splat.glsl"

// Bits: 1 depth, 2 median depth, 4 normal, 8 albedo, 16 roughness, 32 metallic, 64 ao, 128 visibility.
// Keep in sync with engine/src/splat/mod.rs `Channels::bits`.
layout(constant_id = 0) const uint CHANNELS = 0;
const bool FEATURES = (CHANNELS & 252u) != 0u;

void main() {
    uint tile = block_index();
    uint tiles_x = frame.size.z;
    uint local = gl_LocalInvocationID.x;
    uvec2 pix = uvec2(tile % tiles_x, tile / tiles_x) * TILE + uvec2(local % TILE, local / TILE);
    bool inside = pix.x < frame.size.x && pix.y < frame.size.y;
    if (!inside) return;
    vec2 centre = vec2(pix) + 0.5;
    uvec2 range = Uvec2s(frame.work2.xy).v[tile];
    Uints values = Uints(frame.work1.zw);
    Splats splats = Splats(frame.scene5.zw);
    Features features = Features(frame.work0.xy);

    float T = 1.0;
    vec3 rgb = vec3(0.0);
    float depth = 0.0, median = 0.0;
    vec3 normal = vec3(0.0), albedo = vec3(0.0);
    float rough = 0.0, metal = 0.0, ao = 0.0, vis = 0.0;
    for (uint j = range.x; j < range.y; j++) {
#ifdef SUBGROUP_LOADS
        // Every active lane reads the same splat: one elected lane loads, the
        // subgroup shares (any subgroup size; per-lane loads are slow on lavapipe).
        uint g = 0u;
        vec4 head = vec4(0.0), conic = vec4(0.0);
        if (subgroupElect()) {
            g = values.v[j];
            head = splats.v[g].head;  // mean, depth, opacity
            conic = splats.v[g].conic;
        }
        g = subgroupBroadcastFirst(g);
        head = subgroupBroadcastFirst(head);
        conic = subgroupBroadcastFirst(conic);
#else
        uint g = values.v[j];
        vec4 head = splats.v[g].head;  // mean, depth, opacity
        vec4 conic = splats.v[g].conic;
#endif
        vec2 d = head.xy - centre;
        float power = -0.5 * (conic.x * d.x * d.x + conic.z * d.y * d.y) - conic.y * d.x * d.y;
        if (power > 0.0) continue;
        float alpha = min(0.99, head.w * exp(power));
        if (alpha < 1.0 / 255.0) continue;
        float next_T = T * (1.0 - alpha);
        if (next_T < 1e-4) break;
        float w = alpha * T;
        rgb += w * splats.v[g].color.rgb;
        if ((CHANNELS & 1u) != 0u) depth += w * head.z;
        if ((CHANNELS & 2u) != 0u && T > 0.5 && next_T <= 0.5) median = head.z;
        if (FEATURES) {
            vec4 f0 = features.v[3 * g], f1 = features.v[3 * g + 1], f2 = features.v[3 * g + 2];
            normal += w * f0.xyz;
            rough += w * f0.w;
            albedo += w * f1.xyz;
            metal += w * f1.w;
            ao += w * f2.x;
            vis += w * f2.y;
        }
        T = next_T;
    }
    uint p = pix.y * frame.size.x + pix.x;
    vec3 color = rgb + T * frame.background.rgb;
    Floats out_rgb = Floats(frame.work2.zw);
    out_rgb.v[3 * p] = color.r;
    out_rgb.v[3 * p + 1] = color.g;
    out_rgb.v[3 * p + 2] = color.b;
    Floats(frame.out0.xy).v[p] = 1.0 - T;
    if ((CHANNELS & 1u) != 0u) Floats(frame.out0.zw).v[p] = depth;
    if ((CHANNELS & 2u) != 0u) Floats(frame.out1.xy).v[p] = median;
    if ((CHANNELS & 4u) != 0u) {
        Floats o = Floats(frame.out1.zw);
        o.v[3 * p] = normal.x;
        o.v[3 * p + 1] = normal.y;
        o.v[3 * p + 2] = normal.z;
    }
    if ((CHANNELS & 8u) != 0u) {
        Floats o = Floats(frame.out2.xy);
        o.v[3 * p] = albedo.r;
        o.v[3 * p + 1] = albedo.g;
        o.v[3 * p + 2] = albedo.b;
    }
    if ((CHANNELS & 16u) != 0u) Floats(frame.out2.zw).v[p] = rough;
    if ((CHANNELS & 32u) != 0u) Floats(frame.out3.xy).v[p] = metal;
    if ((CHANNELS & 64u) != 0u) Floats(frame.out3.zw).v[p] = ao;
    if ((CHANNELS & 128u) != 0u) Floats(frame.out4.xy).v[p] = vis;
}
