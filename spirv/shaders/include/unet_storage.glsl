// Activation storage of the U-Net kernels: fp32, or fp16 with HALF_STORAGE
// (IN_HALF / OUT_HALF specialization constants per layer). Needs
// address.glsl.
#ifndef SRUG_UNET_STORAGE_GLSL
#define SRUG_UNET_STORAGE_GLSL
layout(buffer_reference, std430, buffer_reference_align = 16) writeonly buffer Vec4sOut { vec4 v[]; };

#ifdef HALF_STORAGE
#extension GL_EXT_shader_16bit_storage : require
layout(buffer_reference, std430, buffer_reference_align = 2) readonly buffer HalfsIn { float16_t v[]; };
layout(buffer_reference, std430, buffer_reference_align = 2) writeonly buffer HalfsOut { float16_t v[]; };
layout(constant_id = 10) const bool IN_HALF = true;
layout(constant_id = 11) const bool OUT_HALF = true;

float load_input(uvec2 a, uint i) {
    return IN_HALF ? float(HalfsIn(a).v[i]) : FloatsIn(a).v[i];
}

void store_output(uvec2 a, uint i, float v) {
    if (OUT_HALF) {
        // Saturate: fp16 storage holds ±65504 at most (no overflow to infinity).
        HalfsOut(a).v[i] = float16_t(clamp(v, -65504.0, 65504.0));
    } else {
        FloatsOut(a).v[i] = v;
    }
}

// Stores elements i .. i + 3 (i a multiple of 4, the buffer 16-byte aligned) in one access.
void store_output4(uvec2 a, uint i, vec4 v) {
    if (OUT_HALF) {
        // As two packed 32-bit words: on lavapipe an f16vec4 store made the whole fp16 network 4%
        // slower at 704×192 (256.8 against 246.4 ms).
        vec4 c = clamp(v, vec4(-65504.0), vec4(65504.0));
        Uvec2sOut(a).v[i / 4u] = uvec2(packHalf2x16(c.xy), packHalf2x16(c.zw));
    } else {
        Vec4sOut(a).v[i / 4u] = v;
    }
}
#else
float load_input(uvec2 a, uint i) {
    return FloatsIn(a).v[i];
}

void store_output(uvec2 a, uint i, float v) {
    FloatsOut(a).v[i] = v;
}

// Stores elements i .. i + 3 (i a multiple of 4, the buffer 16-byte aligned) in one access.
void store_output4(uvec2 a, uint i, vec4 v) {
    Vec4sOut(a).v[i / 4u] = v;
}
#endif

#endif
