#version 460
// Deferred shading, one invocation per pixel: L_o = L_sun + L_sky (+ L_ind,
// planar RGB, when the indirect stage ran), composited over the background by alpha
// (the environment along the view ray, or a colour), then exposure, tone
// mapping and sRGB encoding for display. CPU twin: engine/src/shade/cpu.rs `compose_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "shade.glsl"
#include "display.glsl"

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
    write3(shade.out_display, p, display_encode(radiance, shade.display.x, uint(shade.display.y)));
}
