#version 460
// Writes a frame as the texels of a host's image, one invocation per pixel:
// RGBA8/BGRA8 (display values), RGBA16F or RGBA32F (linear), or one f32 depth
// per pixel in the host's convention; composited over the host's own texels
// (copied out of its image before the frame) when asked. The output is copied
// into the image. CPU twin: engine/src/frame/host_images.rs `pack_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"
#include "display.glsl"

// Host mirror: engine/src/frame/host_images.rs `PackUniform` (checked against this block).
layout(std140, set = 0, binding = 0) uniform HostPack {
    uvec4 size;      // width, height, texel format (0 RGBA8, 1 BGRA8, 2 RGBA16F, 3 RGBA32F, 4 f32 depth), flags
    vec4 display;    // exposure multiplier, tone map, unused, unused
    vec4 depth;      // convention (0 camera z, 1 Vulkan [0, 1], 2 reversed-Z), near, far (may be +inf), unused
    uvec2 colour;        // 3 floats per pixel: premultiplied over black, or over the background
    uvec2 alpha;         // coverage
    uvec2 median_depth;  // camera z where coverage crosses 50%, 0: none
    uvec2 host;          // the image's texels before the frame (flag 1)
    uvec2 out_texels;
} pack;

const uint COMPOSITE = 1u;     // blend over the host's texels (colour) or keep the nearer (depth)
const uint DISPLAY = 2u;       // colour is linear radiance to expose, tone-map and encode (8-bit formats)

// The texel's 4 channels as stored (RGBA order), 8-bit ones in [0, 1].
vec4 read_texel(uint format, uint p) {
    UintsIn t = UintsIn(pack.host);
    if (format == 0u) return unpackUnorm4x8(t.v[p]);
    if (format == 1u) return unpackUnorm4x8(t.v[p]).bgra;
    if (format == 2u) return vec4(unpackHalf2x16(t.v[2u * p]), unpackHalf2x16(t.v[2u * p + 1u]));
    return uintBitsToFloat(uvec4(t.v[4u * p], t.v[4u * p + 1u], t.v[4u * p + 2u], t.v[4u * p + 3u]));
}

void write_texel(uint format, uint p, vec4 c) {
    UintsOut o = UintsOut(pack.out_texels);
    if (format == 0u) {
        o.v[p] = packUnorm4x8(c);
    } else if (format == 1u) {
        o.v[p] = packUnorm4x8(c.bgra);
    } else if (format == 2u) {
        o.v[2u * p] = packHalf2x16(c.xy);
        o.v[2u * p + 1u] = packHalf2x16(c.zw);
    } else {
        uvec4 b = floatBitsToUint(c);
        o.v[4u * p] = b.x;
        o.v[4u * p + 1u] = b.y;
        o.v[4u * p + 2u] = b.z;
        o.v[4u * p + 3u] = b.w;
    }
}

// Camera z of a stored depth value; +inf where nothing is there.
// Twin of HostDepth::camera_z (engine/src/splat/mod.rs).
float camera_z(float d) {
    uint convention = uint(pack.depth.x);
    float n = pack.depth.y, f = pack.depth.z;
    float inf = uintBitsToFloat(0x7f800000u);
    if (convention == 0u) return d > 0.0 ? d : inf;
    if (convention == 1u) return d >= 1.0 ? inf : n * f / (f - d * (f - n));
    if (d <= 0.0) return inf;
    return isinf(f) ? n / d : n * f / (n + d * (f - n));
}

// The stored value of camera z `z` (finite, > 0).
float stored_depth(float z) {
    uint convention = uint(pack.depth.x);
    float n = pack.depth.y, f = pack.depth.z;
    if (convention == 0u) return z;
    if (convention == 1u) return clamp(f * (z - n) / (z * (f - n)), 0.0, 1.0);
    return clamp(isinf(f) ? n / z : n * (f - z) / (z * (f - n)), 0.0, 1.0);
}

// The stored value of "nothing here".
float empty_depth() {
    uint convention = uint(pack.depth.x);
    return convention == 1u ? 1.0 : 0.0;
}

void main() {
    uint p = linear_index();
    if (p >= pack.size.x * pack.size.y) return;
    uint format = pack.size.z, flags = pack.size.w;
    bool composite = (flags & COMPOSITE) != 0u;
    if (format == 4u) {
        float z = FloatsIn(pack.median_depth).v[p];
        float splat = z > 0.0 ? stored_depth(z) : empty_depth();
        if (composite) {
            float host = FloatsIn(pack.host).v[p];
            float host_z = camera_z(host);
            // The host's value stays bit for bit unless a splat is nearer, and a nearer
            // splat's stored value never lies behind the host's (storing can round across it).
            bool nearer = z > 0.0 && z < host_z;
            if (nearer && !isinf(host_z)) splat = uint(pack.depth.x) == 2u ? max(splat, host) : min(splat, host);
            splat = nearer ? splat : host;
        }
        FloatsOut(pack.out_texels).v[p] = splat;
        return;
    }
    FloatsIn colour = FloatsIn(pack.colour);
    vec3 c = vec3(colour.v[3u * p], colour.v[3u * p + 1u], colour.v[3u * p + 2u]);
    float a = clamp(FloatsIn(pack.alpha).v[p], 0.0, 1.0);
    vec4 host = composite ? read_texel(format, p) : vec4(0.0);
    vec4 out_texel;
    if ((flags & DISPLAY) != 0u) {
        if (composite) {
            // Blend in linear light: the splats' straight colour, exposed and
            // tone-mapped as a display value, by coverage over the host's display value.
            vec3 straight = a > 0.0 ? c / a : vec3(0.0);
            vec3 splat = srgb_decode3(display_encode(straight, pack.display.x, uint(pack.display.y)));
            vec3 lin = a * splat + (1.0 - a) * srgb_decode3(host.rgb);
            out_texel = vec4(srgb_encode3(lin), a + (1.0 - a) * host.a);
        } else {
            out_texel = vec4(display_encode(c, pack.display.x, uint(pack.display.y)), a);
        }
    } else {
        out_texel = vec4(c, a) + (1.0 - a) * host;
    }
    write_texel(format, p, out_texel);
}
