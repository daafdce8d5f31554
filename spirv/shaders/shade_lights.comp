#version 460
// Deferred shading, one invocation per pixel: L_sun and L_sky from the
// alpha-normalised G-buffer. Sun: f_r · S_i · V · max(N·L, 0) with the
// simplified Cook–Torrance BRDF (GGX D, Schlick F, Schlick–Smith G with
// k = (r+1)²/8). Sky: split-sum IBL, prefiltered(R, r)·(F0·A + B) plus
// (1 − m)·a/π · E(N) · ao. TERMS picks which of sun diffuse (1), sun specular
// (2), sky diffuse (4), sky specular (8) are added. Pixels with alpha below
// the minimum get 0. CPU twin: engine/src/shade/cpu.rs `shade_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "shade.glsl"

layout(constant_id = 0) const uint TERMS = 15;

float channel(uvec2 a, uint p, float inv_alpha, float fallback) {
    return has(a) ? clamp(FloatsIn(a).v[p] * inv_alpha, 0.0, 1.0) : fallback;
}

void main() {
    uint p = linear_index();
    if (p >= shade.size.x * shade.size.y) return;
    float alpha = FloatsIn(shade.alpha).v[p];
    vec3 sun = vec3(0.0), sky = vec3(0.0);
    if (alpha >= shade.env.w) {
        float ia = 1.0 / alpha;
        vec3 v = -pixel_ray(p);
        vec3 n = read3(shade.normal, p);
        float len = length(n);
        n = len > 1e-12 ? n / len : v;
        vec3 albedo = clamp(read3(shade.albedo, p) * ia, 0.0, 1.0);
        float r = channel(shade.roughness, p, ia, 1.0);
        float m = channel(shade.metallic, p, ia, 0.0);
        float ao = channel(shade.ao, p, ia, 1.0);
        float vis = 1.0;
        if (shade.modes.x == 1u) vis = channel(shade.fixed_visibility, p, ia, 1.0);
        if (shade.modes.x == 2u) vis = clamp(FloatsIn(shade.editable_visibility).v[p], 0.0, 1.0);
        vec3 f0 = mix(vec3(0.04), albedo, m);
        vec3 diffuse = (1.0 - m) * albedo / PI;
        float nov = max(dot(n, v), MIN_NOV);
        float alpha_r = r * r;
        vec3 l = shade.sun_dir.xyz;
        float nol = dot(n, l);
        if (shade.sun_dir.w > 0.0 && nol > 0.0 && vis > 0.0) {
            vec3 hv = v + l;
            float hl = length(hv);
            vec3 h = hl > 1e-12 ? hv / hl : n;
            float noh = max(dot(n, h), 0.0);
            float voh = max(dot(v, h), 0.0);
            float k = (r + 1.0) * (r + 1.0) / 8.0;
            float g = g1_schlick(nov, k) * g1_schlick(nol, k);
            // f_s·(N·L) = D·F·G / (4·N·V): N·L cancels.
            vec3 spec = d_ggx(noh, alpha_r) * fresnel_schlick(voh, f0) * g / (4.0 * nov);
            vec3 f = vec3(0.0);
            if ((TERMS & 1u) != 0u) f += diffuse * nol;
            if ((TERMS & 2u) != 0u) f += spec;
            sun = f * shade.sun_radiance.rgb * vis;
        }
        if ((TERMS & 4u) != 0u) {
            vec3 e = latlong_sample(shade.irradiance, 0u, shade.env_size.zw, env_dir(n)) * shade.env.z;
            sky += diffuse * e * ao;
        }
        if ((TERMS & 8u) != 0u) {
            vec3 refl = 2.0 * dot(n, v) * n - v;
            uint levels = shade.size.z;
            vec3 pre = latlong_sample_lod(shade.specular, shade.env_size.xy, levels, env_dir(normalize(refl)),
                                          r * float(levels - 1u)) * shade.env.z;
            float ts = float(shade.size.w - 1u);
            vec2 s = vec2(nov, r) * ts;
            vec2 f = floor(min(s, vec2(ts - 1.0)));
            vec2 w = s - f;
            uint base = uint(f.y) * shade.size.w + uint(f.x);
            Uvec2sIn lut = Uvec2sIn(shade.brdf);
            vec2 t00 = uintBitsToFloat(lut.v[base]), t10 = uintBitsToFloat(lut.v[base + 1u]);
            vec2 t01 = uintBitsToFloat(lut.v[base + shade.size.w]);
            vec2 t11 = uintBitsToFloat(lut.v[base + shade.size.w + 1u]);
            vec2 ab = mix(mix(t00, t10, w.x), mix(t01, t11, w.x), w.y);
            sky += pre * (f0 * ab.x + ab.y);
        }
    }
    write3(shade.l_sun, p, sun);
    write3(shade.l_sky, p, sky);
}
