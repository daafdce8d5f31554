// Shared by the deferred shading kernels: the shade uniform, pixel view rays,
// the environment rotation and the G-buffer reads.
#ifndef SRUG_SHADE_GLSL
#define SRUG_SHADE_GLSL
#include "address.glsl"
#include "camera.glsl"
#include "latlong.glsl"

// Host mirror: engine/src/shade/mod.rs `ShadeUniform` (its layout is checked against this block).
layout(std140, set = 0, binding = 0) uniform Shade {
    CameraToWorld camera;
    uvec4 size;         // width, height, specular levels, BRDF table size
    uvec4 env_size;     // specular level-0 width, height; irradiance width, height
    vec4 sun_dir;       // unit vector toward the sun; w: 1 when there is sun light
    vec4 sun_radiance;  // S_i per channel
    vec4 env;           // cos ρ, sin ρ (environment rotation), intensity, minimum alpha of a surface
    vec4 background;    // rgb; w: 1 shows the environment instead
    vec4 display;       // exposure multiplier, tone map (0 clamp, 1 Reinhard, 2 ACES), unused, unused
    uvec4 modes;        // visibility (0 none, 1 fixed, 2 editable), unused...
    uvec2 normal;               // G-buffer inputs by device address (low, high)
    uvec2 albedo;
    uvec2 roughness;            // 0: 1
    uvec2 metallic;             // 0: 0
    uvec2 ao;                   // 0: 1
    uvec2 fixed_visibility;     // 0: 1
    uvec2 editable_visibility;  // the shadow test's V_e
    uvec2 alpha;
    uvec2 specular;             // prefiltered specular chain
    uvec2 irradiance;
    uvec2 brdf;                 // BRDF table
    uvec2 l_sun;                // L_sun (written by shade_lights, read by shade_compose)
    uvec2 l_sky;
    uvec2 l_ind;                // planar RGB; 0: none
    uvec2 out_radiance;
    uvec2 out_display;
} shade;

bool has(uvec2 a) { return a != uvec2(0u); }

vec3 read3(uvec2 a, uint p) {
    FloatsIn b = FloatsIn(a);
    return vec3(b.v[3u * p], b.v[3u * p + 1u], b.v[3u * p + 2u]);
}

void write3(uvec2 a, uint p, vec3 v) {
    FloatsOut b = FloatsOut(a);
    b.v[3u * p] = v.x;
    b.v[3u * p + 1u] = v.y;
    b.v[3u * p + 2u] = v.z;
}

// Unit world direction of the camera ray through pixel p.
vec3 pixel_ray(uint p) {
    return normalize(camera_ray(shade.camera, pixel_centre(p, shade.size.x)));
}

// A world direction in the environment's own frame (rotated by −ρ about z).
vec3 env_dir(vec3 d) {
    float c = shade.env.x, s = shade.env.y;
    return vec3(d.x * c - d.y * s, d.x * s + d.y * c, d.z);
}

#endif
