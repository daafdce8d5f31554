// Shared by the deferred shading kernels: the shade uniform, pixel view rays,
// the environment rotation and the G-buffer reads.
#ifndef SRUG_SHADE_GLSL
#define SRUG_SHADE_GLSL
#include "address.glsl"
#include "latlong.glsl"

// Keep in sync with engine/src/shade/mod.rs `ShadeUniform` (std140: vec4/uvec4 only).
layout(std140, set = 0, binding = 0) uniform Shade {
    vec4 cam_rot0;      // camera-to-world rotation, rows
    vec4 cam_rot1;
    vec4 cam_rot2;
    vec4 cam_pos;       // w: 0 pinhole, 1 orthographic
    vec4 cam_intr;      // fx, fy, cx, cy (orthographic: pixels per unit)
    uvec4 size;         // width, height, specular levels, BRDF table size
    uvec4 env_size;     // specular level-0 width, height; irradiance width, height
    vec4 sun_dir;       // unit vector toward the sun; w: 1 when there is sun light
    vec4 sun_radiance;  // S_i per channel
    vec4 env;           // cos ρ, sin ρ (environment rotation), intensity, minimum alpha of a surface
    vec4 background;    // rgb; w: 1 shows the environment instead
    vec4 display;       // exposure multiplier, tone map (0 clamp, 1 Reinhard, 2 ACES), unused, unused
    uvec4 modes;        // visibility (0 none, 1 fixed, 2 editable), unused...
    uvec4 addr0;        // normal, albedo
    uvec4 addr1;        // roughness, metallic (0: 1 and 0)
    uvec4 addr2;        // ao, fixed visibility (0: 1)
    uvec4 addr3;        // editable visibility, alpha
    uvec4 addr4;        // specular chain, irradiance
    uvec4 addr5;        // BRDF table, L_sun
    uvec4 addr6;        // L_sky, L_ind (planar RGB; 0: none)
    uvec4 addr7;        // radiance out, display out
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
    uint w = shade.size.x;
    vec2 px = vec2(float(p % w), float(p / w)) + 0.5;
    vec4 k = shade.cam_intr;
    vec3 c = shade.cam_pos.w == 0.0 ? vec3((px - k.zw) / k.xy, 1.0) : vec3(0.0, 0.0, 1.0);
    return normalize(vec3(dot(shade.cam_rot0.xyz, c), dot(shade.cam_rot1.xyz, c), dot(shade.cam_rot2.xyz, c)));
}

// A world direction in the environment's own frame (rotated by −ρ about z).
vec3 env_dir(vec3 d) {
    float c = shade.env.x, s = shade.env.y;
    return vec3(d.x * c - d.y * s, d.x * s + d.y * c, d.z);
}

#endif
