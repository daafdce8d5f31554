#version 460
// The split-sum environment BRDF table: for N·V (columns, i/(size−1), N·V
// clamped ≥ 1e-4) and roughness (rows, j/(size−1)), the scale A and bias B
// with ∫ f_r cos = F0·A + B, by GGX importance sampling over a Hammersley set.
// VARIANT 0: Schlick–Smith G with k = α/2 (Karis 2013); 1: height-correlated
// Smith GGX (nvdiffrec and the relighting codes derived from it).
// CPU twin: engine/src/shade/cpu.rs `brdf_lut_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"
#include "brdf.glsl"

layout(constant_id = 0) const uint VARIANT = 0;

// Keep in sync with engine/src/shade/env.rs `LutPush`.
layout(push_constant) uniform LutPush {
    uvec2 dst;      // vec2 per texel
    uint size;
    uint samples;
} push;

void main() {
    uint i = linear_index();
    if (i >= push.size * push.size) return;
    float nov = max(float(i % push.size) / float(push.size - 1u), MIN_NOV);
    float r = float(i / push.size) / float(push.size - 1u);
    float alpha = r * r;
    vec3 v = vec3(sqrt(1.0 - nov * nov), 0.0, nov);
    float a = 0.0, b = 0.0;
    for (uint s = 0u; s < push.samples; ++s) {
        vec3 h = sample_ggx(hammersley(s, push.samples), alpha);
        float voh = dot(v, h);
        vec3 l = 2.0 * voh * h - v;
        float nol = l.z;
        if (nol <= 0.0) continue;
        float noh = max(h.z, 0.0);
        voh = max(voh, 0.0);
        float g;
        if (VARIANT == 0u) {
            float k = alpha * 0.5;
            g = g1_schlick(nov, k) * g1_schlick(nol, k);
        } else {
            g = 1.0 / (1.0 + lambda_ggx(nov, alpha) + lambda_ggx(nol, alpha));
        }
        float g_vis = g * voh / max(noh * nov, 1e-30);
        float fc = pow(1.0 - voh, 5.0);
        a += (1.0 - fc) * g_vis;
        b += fc * g_vis;
    }
    FloatsOut o = FloatsOut(push.dst);
    o.v[2u * i] = a / float(push.samples);
    o.v[2u * i + 1u] = b / float(push.samples);
}
