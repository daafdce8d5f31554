// Display encoding shared by the shading composite and the host-image writer:
// tone mapping (0 clamp, 1 Reinhard, 2 ACES fit) and the sRGB transfer function.
// CPU twins: engine/src/shade/cpu.rs `tone_map`, `srgb_encode`, `srgb_decode`.
#ifndef SRUG_DISPLAY_GLSL
#define SRUG_DISPLAY_GLSL

vec3 tone_map(vec3 c, uint op) {
    if (op == 1u) return c / (1.0 + c);
    if (op == 2u) return (c * (2.51 * c + 0.03)) / (c * (2.43 * c + 0.59) + 0.14);
    return c;
}

float srgb_encode(float c) {
    c = clamp(c, 0.0, 1.0);
    return c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}

float srgb_decode(float c) {
    c = clamp(c, 0.0, 1.0);
    return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

vec3 srgb_encode3(vec3 c) { return vec3(srgb_encode(c.x), srgb_encode(c.y), srgb_encode(c.z)); }
vec3 srgb_decode3(vec3 c) { return vec3(srgb_decode(c.x), srgb_decode(c.y), srgb_decode(c.z)); }

// Exposure (a multiplier), tone map `op`, then sRGB encoding: a display value in [0, 1].
vec3 display_encode(vec3 radiance, float exposure, uint op) {
    return srgb_encode3(max(tone_map(max(radiance * exposure, 0.0), op), 0.0));
}

#endif
