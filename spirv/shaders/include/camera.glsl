// The camera as every uniform block carries it, and the pixel/ray maths on it.
// Host mirror: engine/src/camera.rs `CameraToWorldBlock` and
// `WorldToCameraBlock` (packed once by `Camera::packed`; each block that
// embeds one is checked member by member against the host struct).
// Pixel centres sit at +0.5 (docs/conventions.md).
#ifndef SRUG_CAMERA_GLSL
#define SRUG_CAMERA_GLSL

// For unprojecting pixels: camera-to-world rotation and the camera centre.
struct CameraToWorld {
    vec4 rot0;        // camera-to-world rotation, rows
    vec4 rot1;
    vec4 rot2;
    vec4 position;    // camera centre; w: 0 pinhole, 1 orthographic
    vec4 intrinsics;  // fx, fy, cx, cy (orthographic: pixels per unit x, y, cx, cy)
};

// For projecting points: world-to-camera rotation and translation.
struct WorldToCamera {
    vec4 rot0;         // world-to-camera rotation, rows
    vec4 rot1;
    vec4 rot2;
    vec4 translation;  // world-to-camera translation; w: 0 pinhole, 1 orthographic
    vec4 intrinsics;   // fx, fy, cx, cy (orthographic: pixels per unit x, y, cx, cy)
};

// The world-to-camera rotation as a matrix (its columns built from the rows).
mat3 world_to_camera_rotation(WorldToCamera c) {
    return transpose(mat3(c.rot0.xyz, c.rot1.xyz, c.rot2.xyz));
}

// Centre of pixel index p in an image `width` pixels wide.
vec2 pixel_centre(uint p, uint width) {
    return vec2(float(p % width), float(p / width)) + 0.5;
}

// A camera-space vector rotated into the world.
vec3 camera_vector_to_world(CameraToWorld c, vec3 v) {
    return vec3(dot(c.rot0.xyz, v), dot(c.rot1.xyz, v), dot(c.rot2.xyz, v));
}

// World direction of the ray through pixel px, scaled to camera depth 1
// (pinhole) or the optical axis (orthographic); not normalised.
vec3 camera_ray(CameraToWorld c, vec2 px) {
    vec4 k = c.intrinsics;
    vec3 v = c.position.w == 0.0 ? vec3((px - k.zw) / k.xy, 1.0) : vec3(0.0, 0.0, 1.0);
    return camera_vector_to_world(c, v);
}

// World point seen at pixel px at camera depth z.
vec3 camera_unproject(CameraToWorld c, vec2 px, float z) {
    vec4 k = c.intrinsics;
    vec3 v = c.position.w == 0.0 ? vec3((px - k.zw) / k.xy * z, z) : vec3((px - k.zw) / k.xy, z);
    return camera_vector_to_world(c, v) + c.position.xyz;
}

#endif
