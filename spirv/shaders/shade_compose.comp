#version 460
// Deferred shading, one invocation per pixel: L_o = L_sun + L_sky (+ L_ind,
// planar RGB, when the indirect stage ran), composited over the background by alpha
// (the environment along the view ray, or a colour), then exposure, tone
// mapping and sRGB encoding for display. CPU twin: engine/src/shade/cpu.rs `compose_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "shade.glsl"

vec3 tone_map(vec3 c, uint op) {
    if (op == 1u) return c / (1.0 + c);
    if (op == 2u) return (c * (2.51 * c + 0.03)) / (c * (2.43 * c + 0.59) + 0.14);
    return c;
}

float srgb_encode(float c) {
    c = clamp(c, 0.0, 1.0);
    return c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}

void main() {
    uint p = linear_index();
    if (p >= shade.size.x * shade.size.y) return;
    float alpha = clamp(FloatsIn(shade.alpha).v[p], 0.0, 1.0);
    vec3 lo = vec3(0.0);
    if (alpha >= shade.env.w) {
        lo = read3(shade.l_sun, p) + read3(shade.l_sky, p);
        if (has(shade.l_ind)) {
            // L_ind is planar (CHW), as the indirect network writes it.
            FloatsIn ind = FloatsIn(shade.l_ind);
            uint n = shade.size.x * shade.size.y;
            lo += vec3(ind.v[p], ind.v[n + p], ind.v[2u * n + p]);
        }
    }
    vec3 bg = shade.background.w > 0.0
        ? latlong_sample(shade.specular, 0u, shade.env_size.xy, env_dir(pixel_ray(p))) * shade.env.z
        : shade.background.rgb;
    vec3 radiance = alpha * lo + (1.0 - alpha) * bg;
    write3(shade.out_radiance, p, radiance);
    vec3 c = max(tone_map(max(radiance * shade.display.x, 0.0), uint(shade.display.y)), 0.0);
    write3(shade.out_display, p, vec3(srgb_encode(c.x), srgb_encode(c.y), srgb_encode(c.z)));
}
