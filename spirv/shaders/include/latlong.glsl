// Lat-long environment maps in world space (z up): column u = 0.5 + φ/2π with
// φ the azimuth from north (+y) toward east (+x), row v = 0.5 − θ/π with θ the
// elevation, so the image centre looks north at the horizon and the top row
// is the zenith. Texels are RGB float triples, rows top to bottom; several
// levels share one buffer at texel offsets. Bilinear filtering wraps in u and
// clamps in v. Keep in sync with engine/src/shade/env.rs and shade/cpu.rs.
#ifndef SRUG_LATLONG_GLSL
#define SRUG_LATLONG_GLSL
#include "address.glsl"
#include "brdf.glsl"

// Texel coordinates (centres at +0.5) of a world direction in a w×h map.
vec2 latlong_coords(vec3 d, uvec2 size) {
    float phi = atan(d.x, d.y);
    // atan rather than asin: Mesa lowers asin to a coarse polynomial (~1e-4 rad).
    float theta = atan(d.z, length(d.xy));
    return vec2((0.5 + phi / (2.0 * PI)) * float(size.x), (0.5 - theta / PI) * float(size.y));
}

// Direction through the centre of texel (x, y).
vec3 latlong_direction(uvec2 texel, uvec2 size) {
    float phi = ((float(texel.x) + 0.5) / float(size.x) - 0.5) * 2.0 * PI;
    float theta = (0.5 - (float(texel.y) + 0.5) / float(size.y)) * PI;
    return vec3(cos(theta) * sin(phi), cos(theta) * cos(phi), sin(theta));
}

vec3 latlong_texel(uvec2 addr, uint offset, uvec2 size, int x, int y) {
    x = x % int(size.x);
    if (x < 0) x += int(size.x);
    y = clamp(y, 0, int(size.y) - 1);
    uint i = 3u * (offset + uint(y) * size.x + uint(x));
    FloatsIn m = FloatsIn(addr);
    return vec3(m.v[i], m.v[i + 1u], m.v[i + 2u]);
}

// Bilinear sample of one level along direction d.
vec3 latlong_sample(uvec2 addr, uint offset, uvec2 size, vec3 d) {
    vec2 s = latlong_coords(d, size) - 0.5;
    vec2 f = floor(s);
    vec2 w = s - f;
    int x = int(f.x), y = int(f.y);
    return mix(mix(latlong_texel(addr, offset, size, x, y), latlong_texel(addr, offset, size, x + 1, y), w.x),
               mix(latlong_texel(addr, offset, size, x, y + 1), latlong_texel(addr, offset, size, x + 1, y + 1), w.x),
               w.y);
}

// Size of level l of a chain whose level 0 is base.
uvec2 level_size(uvec2 base, uint l) {
    return max(base >> l, uvec2(1u));
}

// Texel offset of level l.
uint level_offset(uvec2 base, uint l) {
    uint o = 0u;
    for (uint i = 0u; i < l; ++i) {
        uvec2 s = level_size(base, i);
        o += s.x * s.y;
    }
    return o;
}

// Trilinear sample of a chain with `levels` levels at fractional level lod.
vec3 latlong_sample_lod(uvec2 addr, uvec2 base, uint levels, vec3 d, float lod) {
    lod = clamp(lod, 0.0, float(levels - 1u));
    uint l0 = uint(floor(lod));
    uint l1 = min(l0 + 1u, levels - 1u);
    float t = lod - float(l0);
    vec3 a = latlong_sample(addr, level_offset(base, l0), level_size(base, l0), d);
    if (t == 0.0 || l1 == l0) return a;
    vec3 b = latlong_sample(addr, level_offset(base, l1), level_size(base, l1), d);
    return mix(a, b, t);
}

#endif
