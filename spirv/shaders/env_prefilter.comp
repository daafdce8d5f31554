#version 460
// Split-sum specular prefilter, one invocation per output texel of one level:
// the environment convolved with GGX lobes of the level's roughness around
// N = V = R (Karis 2013), weighted by N·L, with filtered importance sampling
// (each sample reads the pyramid level whose texels match its solid angle,
// Colbert & Křivánek 2007) so a few hundred samples give a smooth result.
// Roughness 0 copies the source. CPU twin: engine/src/shade/cpu.rs `prefilter_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "latlong.glsl"

// Keep in sync with engine/src/shade/env.rs `PrefilterPush`.
layout(push_constant) uniform PrefilterPush {
    uvec2 pyramid;   // source pyramid (level 0 first)
    uvec2 dst;       // output level
    uvec2 base;      // pyramid level-0 size
    uvec2 dst_size;
    uint levels;     // pyramid levels
    float roughness;
    uint samples;
    uint pad;
} push;

void main() {
    uint i = linear_index();
    if (i >= push.dst_size.x * push.dst_size.y) return;
    vec3 n = latlong_direction(uvec2(i % push.dst_size.x, i / push.dst_size.x), push.dst_size);
    vec3 c;
    if (push.roughness <= 0.0) {
        c = latlong_sample(push.pyramid, 0u, push.base, n);
    } else {
        float alpha = push.roughness * push.roughness;
        vec3 t, b;
        tangent_frame(n, t, b);
        float texel_solid_angle = 4.0 * PI / float(push.base.x * push.base.y);
        vec3 sum = vec3(0.0);
        float weight = 0.0;
        for (uint s = 0u; s < push.samples; ++s) {
            vec3 hl = sample_ggx(hammersley(s, push.samples), alpha);
            vec3 h = hl.x * t + hl.y * b + hl.z * n;
            float noh = hl.z;
            vec3 l = 2.0 * noh * h - n;
            float nol = dot(n, l);
            if (nol <= 0.0) continue;
            // pdf of l: D·NoH / (4·VoH) with V = N, so D / 4.
            float pdf = d_ggx(noh, alpha) * 0.25;
            float sample_solid_angle = 1.0 / (float(push.samples) * pdf + 1e-30);
            float lod = max(0.5 * log2(sample_solid_angle / texel_solid_angle) + 1.0, 0.0);
            sum += latlong_sample_lod(push.pyramid, push.base, push.levels, normalize(l), lod) * nol;
            weight += nol;
        }
        c = weight > 0.0 ? sum / weight : latlong_sample(push.pyramid, 0u, push.base, n);
    }
    FloatsOut o = FloatsOut(push.dst);
    o.v[3u * i] = c.x;
    o.v[3u * i + 1u] = c.y;
    o.v[3u * i + 2u] = c.z;
}
