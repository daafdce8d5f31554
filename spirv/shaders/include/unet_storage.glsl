// Activation storage of the U-Net kernels: fp32, or fp16 with HALF_STORAGE
// (IN_HALF / OUT_HALF specialization constants per layer). Needs
// address.glsl.
#ifndef SRUG_UNET_STORAGE_GLSL
#define SRUG_UNET_STORAGE_GLSL
layout(buffer_reference, std430, buffer_reference_align = 16) writeonly buffer Vec4sOut { vec4 v[]; };

#ifdef HALF_STORAGE
#extension GL_EXT_shader_16bit_storage : require
layout(buffer_reference, std430, buffer_reference_align = 2) readonly buffer HalfsIn { float16_t v[]; };
layout(buffer_reference, std430, buffer_reference_align = 2) writeonly buffer HalfBitsOut { uint16_t v[]; };
layout(constant_id = 10) const bool IN_HALF = true;
layout(constant_id = 11) const bool OUT_HALF = true;

float load_input(uvec2 a, uint i) {
    return IN_HALF ? float(HalfsIn(a).v[i]) : FloatsIn(a).v[i];
}

// The fp16 bits of v, rounded to nearest even, saturated to ±65504 (fp16 storage holds no more; no
// overflow to infinity); NaN becomes a quiet NaN. By integer operations, which beat llvmpipe's own
// conversion (float16_t(), packHalf2x16); docs/bench/unet.md has the figures.
// CPU twin: engine/src/indirect/cpu.rs `half_bits` (keep in sync).
uint half_bits(float v) {
    uint f = floatBitsToUint(v);
    uint a = min(f & 0x7fffffffu, 0x477fe000u); // saturate at 65504 (and keep NaN apart below)
    // Normal: rebias the exponent (−112 << 23) and round half to even at bit 13.
    uint normal = (a + 0xc8000fffu + ((a >> 13u) & 1u)) >> 13u;
    // Below 2^-14 (subnormal in fp16): adding 0.5 makes the fp32 adder round at fp16's 2^-24 step.
    uint subnormal = floatBitsToUint(uintBitsToFloat(a) + 0.5) - 0x3f000000u;
    uint bits = a < 0x38800000u ? subnormal : normal;
    return ((f >> 16u) & 0x8000u) | ((f & 0x7fffffffu) > 0x7f800000u ? 0x7e00u : bits);
}

void store_output(uvec2 a, uint i, float v) {
    if (OUT_HALF) {
        HalfBitsOut(a).v[i] = uint16_t(half_bits(v));
    } else {
        FloatsOut(a).v[i] = v;
    }
}

// Stores elements i .. i + 3 (i a multiple of 4, the buffer 16-byte aligned) in one access.
void store_output4(uvec2 a, uint i, vec4 v) {
    if (OUT_HALF) {
        // As two 32-bit words (on lavapipe an f16vec4 store was slower still).
        uvec4 h = uvec4(half_bits(v.x), half_bits(v.y), half_bits(v.z), half_bits(v.w));
        Uvec2sOut(a).v[i / 4u] = uvec2(h.x | (h.y << 16u), h.z | (h.w << 16u));
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
