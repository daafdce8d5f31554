// Shared by the shadow kernels: the shadow uniform, receiver reconstruction,
// light-space projection, shadow-map sampling and the stable sigmoid.
#ifndef SRUG_SHADOW_GLSL
#define SRUG_SHADOW_GLSL
#include "address.glsl"
#include "camera.glsl"

// Host mirror: engine/src/shadow/mod.rs `ShadowUniform` (its layout is checked against this block).
layout(std140, set = 0, binding = 0) uniform Shadow {
    CameraToWorld camera;  // the receivers' camera
    vec4 light_rot0;   // world-to-light rotation, rows
    vec4 light_rot1;
    vec4 light_rot2;
    vec4 camera_in_light;  // the receivers' camera in light space (world-to-light rotation · (its position − the light's)); w: far plane
    vec4 light_intr;   // texels per unit x, y, cx, cy
    uvec4 size;        // camera width, height, map width, height
    vec4 params;       // k, bias, minimum alpha of a surface, depth of an empty texel
    uvec4 modes;       // map depth (0 expected, 1 median, 2 expected over far), receiver depth (0, 1), map tiles across, map tile edge
    vec4 geometry;     // slope bias and normal offset in world units (per texel), the largest tan θ, 0
    vec4 receiver_range;  // camera depths of the receivers a culled map serves (x..y; shadow_receiver_tiles.comp)
    uvec2 receiver_depth;     // by device address (low, high)
    uvec2 receiver_alpha;
    uvec2 map_depth;
    uvec2 map_alpha;
    uvec2 visibility;         // out; 0 in the backward pass
    uvec2 receiver_normal;    // the receivers' normal channel (3 floats a pixel) where geometry.xy ≠ 0
    uvec2 splats;             // the map's splats and sorted pairs (traced test)
    uvec2 sorted_gaussians;
    uvec2 ranges;
    uvec2 tile_mask;          // u32 per map tile (shadow_receiver_tiles.comp)
} shadow;

// How the test reads the map (engine/src/shadow/mod.rs `ShadowFilter`): 0 one
// test of the bilinear depth, 1 the four texels' tests weighted bilinearly (PCF).
layout(constant_id = 1) const uint FILTER = 0;

// Depth of one pixel of a G-buffer: expected (Σwz / alpha) or median; false
// where nothing (alpha below the minimum, or no median crossing) covers it.
bool resolve_depth(uint mode, uvec2 depth_addr, uvec2 alpha_addr, uint p, out float z) {
    if (mode == 1u) {
        z = FloatsIn(depth_addr).v[p];
        return z > 0.0;
    }
    float a = FloatsIn(alpha_addr).v[p];
    z = FloatsIn(depth_addr).v[p] / a;
    return a >= shadow.params.z;
}

// The point seen at receiver pixel p, as world − the receivers' camera
// position (`light_coords` takes it so), and its depth bias; false where there
// is no surface. With a geometric bias (geometry.xy ≠ 0) and a normal n (faced
// toward the camera) at angle θ to the sun, the point moves n·normal offset·sin θ
// and the bias grows by slope bias·min(tan θ, largest tan θ).
bool receiver_point(uint p, out vec3 from_camera, out float bias) {
    float z;
    from_camera = vec3(0.0);
    bias = shadow.params.y;
    if (!resolve_depth(shadow.modes.y, shadow.receiver_depth, shadow.receiver_alpha, p, z)) return false;
    from_camera = camera_unproject_from_camera(shadow.camera, pixel_centre(p, shadow.size.x), z);
    if (shadow.geometry.x != 0.0 || shadow.geometry.y != 0.0) {
        FloatsIn normals = FloatsIn(shadow.receiver_normal);
        vec3 n = vec3(normals.v[3u * p], normals.v[3u * p + 1u], normals.v[3u * p + 2u]);
        float len = length(n);
        if (len > 1e-12) {
            n /= len;
            if (dot(n, from_camera) > 0.0) n = -n;
            float c = clamp(-dot(n, shadow.light_rot2.xyz), 0.0, 1.0);
            float s = sqrt(max(1.0 - c * c, 0.0));
            from_camera += n * (shadow.geometry.y * s);
            bias += shadow.geometry.x * min(s / max(c, 1e-6), shadow.geometry.z);
        }
    }
    return true;
}

// Light-space texel coordinates (centres at +0.5) and depth of a point given
// as world − the receivers' camera position (`receiver_point`), through the
// camera's own light-space position (the host's, in f64): no world coordinate,
// however far from the origin, enters the sum.
vec3 light_coords(vec3 from_camera) {
    vec3 t = vec3(dot(shadow.light_rot0.xyz, from_camera), dot(shadow.light_rot1.xyz, from_camera),
                  dot(shadow.light_rot2.xyz, from_camera)) + shadow.camera_in_light.xyz;
    vec4 k = shadow.light_intr;
    return vec3(k.xy * t.xy + k.zw, t.z);
}

// Depth z_s of one shadow-map texel; empty texels read params.w (the light's
// far depth; twice that in mode 2, expected over far: Σwz + T·empty, defined
// everywhere).
float texel_depth(ivec2 t) {
    uint i = uint(t.y) * shadow.size.z + uint(t.x);
    float far = shadow.params.w;
    if (shadow.modes.x == 2u) {
        return FloatsIn(shadow.map_depth).v[i] + (1.0 - FloatsIn(shadow.map_alpha).v[i]) * far;
    }
    float z;
    return resolve_depth(shadow.modes.x, shadow.map_depth, shadow.map_alpha, i, z) ? z : far;
}

// Bilinear footprint of light coordinates uv: the four texels (clamped to the
// edge) and their weights, in the order (x0,y0), (x1,y0), (x0,y1), (x1,y1).
void bilinear(vec2 uv, out ivec2 t[4], out vec4 w) {
    vec2 s = uv - 0.5;
    vec2 f = floor(s);
    vec2 fr = s - f;
    ivec2 hi = ivec2(shadow.size.zw) - 1;
    ivec2 a = clamp(ivec2(f), ivec2(0), hi), b = clamp(ivec2(f) + 1, ivec2(0), hi);
    t[0] = a; t[1] = ivec2(b.x, a.y); t[2] = ivec2(a.x, b.y); t[3] = b;
    w = vec4((1.0 - fr.x) * (1.0 - fr.y), fr.x * (1.0 - fr.y), (1.0 - fr.x) * fr.y, fr.x * fr.y);
}

bool inside_map(vec2 uv) {
    return uv.x >= 0.0 && uv.y >= 0.0 && uv.x < float(shadow.size.z) && uv.y < float(shadow.size.w);
}

// The shadow logit k·(z_s − z + bias), clamped to ±30 (σ is 1 − 9e-14 there;
// the clamp keeps exp finite for any k); NaN-free for finite inputs.
const float LOGIT_LIMIT = 30.0;
float shadow_logit(float zs, float z, float bias) {
    float x = shadow.params.x * (zs - z + bias);
    return clamp(x, -LOGIT_LIMIT, LOGIT_LIMIT);
}

// σ(x) without overflow: e = exp(−|x|) ≤ 1.
float stable_sigmoid(float x) {
    float e = exp(-abs(x));
    return x >= 0.0 ? 1.0 / (1.0 + e) : e / (1.0 + e);
}

#endif
