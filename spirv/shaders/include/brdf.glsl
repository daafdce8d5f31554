// The microfacet BRDF of the paper's appendix and the sampling helpers of
// split-sum image-based lighting (Karis 2013). Keep in sync with the CPU twin
// engine/src/shade/cpu.rs (same formulas, f64).
#ifndef SRUG_BRDF_GLSL
#define SRUG_BRDF_GLSL

const float PI = 3.14159265358979;
// N·V is clamped from below: at 0 the textbook formulas divide 0 by 0.
const float MIN_NOV = 1e-4;

// GGX normal distribution, α = roughness².
float d_ggx(float noh, float alpha) {
    float a2 = alpha * alpha;
    float d = noh * noh * (a2 - 1.0) + 1.0;
    return a2 / max(PI * d * d, 1e-30);
}

// Schlick–Smith masking for one direction with remapping k.
float g1_schlick(float x, float k) {
    return x / (x * (1.0 - k) + k);
}

// Smith Λ of GGX for a direction at cos θ = x.
float lambda_ggx(float x, float alpha) {
    float x2 = max(x * x, 1e-12);
    return 0.5 * (-1.0 + sqrt(1.0 + alpha * alpha * (1.0 - x2) / x2));
}

// Fresnel–Schlick.
vec3 fresnel_schlick(float voh, vec3 f0) {
    float f = pow(1.0 - clamp(voh, 0.0, 1.0), 5.0);
    return f0 + (1.0 - f0) * f;
}

// Point i of an n-point Hammersley set.
vec2 hammersley(uint i, uint n) {
    return vec2(float(i) / float(n), float(bitfieldReverse(i)) * 2.3283064365386963e-10);
}

// GGX-distributed half vector around +z for a uniform point xi.
vec3 sample_ggx(vec2 xi, float alpha) {
    float phi = 2.0 * PI * xi.x;
    // tan²θ = α²ξ/(1 − ξ): exact at α = 0 (sinθ from 1 − cos²θ is not: a cosθ off by one ulp tilts H by
    // 3e-4 rad, which at grazing N·V swamps N·L). Hammersley ξ < 1. Keep in sync with shade/cpu.rs.
    float tan2 = alpha * alpha * xi.y / (1.0 - xi.y);
    float cos_t = inversesqrt(1.0 + tan2);
    float sin_t = sqrt(tan2) * cos_t;
    return vec3(sin_t * cos(phi), sin_t * sin(phi), cos_t);
}

// An orthonormal frame (t, b) around unit n.
void tangent_frame(vec3 n, out vec3 t, out vec3 b) {
    vec3 up = abs(n.z) < 0.999 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0);
    t = normalize(cross(up, n));
    b = cross(n, t);
}

#endif
