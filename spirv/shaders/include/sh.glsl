// Real spherical harmonics up to degree 3, the 3DGS convention
// (same constants and signs as the INRIA and gsplat rasterizers).
// CPU twin: engine/src/splat/cpu.rs `sh_color`.
#ifndef SRUG_SH_GLSL
#define SRUG_SH_GLSL

const float SH_C0 = 0.28209479177387814;
const float SH_C1 = 0.4886025119029199;
const float SH_C2[5] = float[](1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396);
const float SH_C3[7] = float[](-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154, -0.4570457994644658, 1.445305721320277, -0.5900435899266435);

// Basis value k (0..15) for unit direction d.
float sh_basis(uint k, vec3 d) {
    float x = d.x, y = d.y, z = d.z;
    float xx = x * x, yy = y * y, zz = z * z;
    switch (k) {
        case 0: return SH_C0;
        case 1: return -SH_C1 * y;
        case 2: return SH_C1 * z;
        case 3: return -SH_C1 * x;
        case 4: return SH_C2[0] * x * y;
        case 5: return SH_C2[1] * y * z;
        case 6: return SH_C2[2] * (2.0 * zz - xx - yy);
        case 7: return SH_C2[3] * x * z;
        case 8: return SH_C2[4] * (xx - yy);
        case 9: return SH_C3[0] * y * (3.0 * xx - yy);
        case 10: return SH_C3[1] * x * y * z;
        case 11: return SH_C3[2] * y * (4.0 * zz - xx - yy);
        case 12: return SH_C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy);
        case 13: return SH_C3[4] * x * (4.0 * zz - xx - yy);
        case 14: return SH_C3[5] * z * (xx - yy);
        default: return SH_C3[6] * x * (xx - 3.0 * yy);
    }
}

#endif
