/* Renders the demo city through the C API, the way an embedding engine would.
 *
 * usage: render SCENE.ply CAMERA.txt OUT.rgba
 * CAMERA.txt: width height fx fy cx cy, 16 camera-to-world floats (column-major,
 * OpenCV axes), near far, sun azimuth, elevation. Writes the relit frame as
 * tightly packed RGBA8 rows to OUT.rgba for the Rust test to compare with the
 * Rust API's image. Checks along the way: scene from memory equals scene from
 * file, the camera given as OpenGL matrices gives the same image, channels,
 * timings, memory, the shadow forward/backward pass, two threads rendering at
 * once, and zero validation messages. */
#define _GNU_SOURCE /* dl_iterate_phdr, RTLD_NODELETE */
#include <math.h>
#include <pthread.h>
#include <stdint.h>

#include "check.h"

typedef struct {
  srug_renderer *renderer;
  srug_scene *scene;
  srug_status status;
} job;

static void *render_job(void *arg) {
  job *j = arg;
  j->status = srug_renderer_render(j->renderer, j->scene);
  return NULL;
}

static unsigned char *read_file(const char *path, size_t *len) {
  FILE *f = fopen(path, "rb");
  REQUIRE(f != NULL);
  REQUIRE(fseek(f, 0, SEEK_END) == 0);
  long n = ftell(f);
  REQUIRE(n > 0);
  REQUIRE(fseek(f, 0, SEEK_SET) == 0);
  unsigned char *data = malloc((size_t)n);
  REQUIRE(data != NULL);
  REQUIRE(fread(data, 1, (size_t)n, f) == (size_t)n);
  fclose(f);
  *len = (size_t)n;
  return data;
}

/* Reads the frame as RGBA8 rows `stride` bytes apart and returns them tightly packed. */
static unsigned char *read_rgba8(srug_renderer *r, uint32_t w, uint32_t h) {
  size_t stride = (size_t)w * 4 + 12; /* padded rows, as a texture upload might have */
  size_t len = stride * h;
  unsigned char *padded = malloc(len);
  unsigned char *tight = malloc((size_t)w * h * 4);
  REQUIRE(padded != NULL && tight != NULL);
  memset(padded, 0xAB, len);
  CHECK(srug_renderer_read_image(r, SRUG_FORMAT_RGBA8_SRGB, padded, len, stride));
  for (uint32_t y = 0; y < h; y++) {
    memcpy(tight + (size_t)y * w * 4, padded + (size_t)y * stride, (size_t)w * 4);
    for (size_t k = (size_t)w * 4; k < stride; k++) REQUIRE(padded[(size_t)y * stride + k] == 0xAB);
  }
  free(padded);
  return tight;
}

/* Renders `scene` with the renderer's current settings and returns the mean absolute
   difference (of 255) of its RGBA8 frame from `image`. */
static double rerender_difference(srug_renderer *r, const srug_scene *scene, const unsigned char *image,
                                  uint32_t w, uint32_t h) {
  CHECK(srug_renderer_render(r, scene));
  unsigned char *frame = read_rgba8(r, w, h);
  size_t n = (size_t)w * h * 4;
  double sum = 0.0;
  for (size_t i = 0; i < n; i++) sum += fabs((double)frame[i] - (double)image[i]);
  free(frame);
  return sum / (double)n;
}

static int max_difference(const unsigned char *a, const unsigned char *b, size_t n) {
  int worst = 0;
  for (size_t i = 0; i < n; i++) {
    int d = abs((int)a[i] - (int)b[i]);
    if (d > worst) worst = d;
  }
  return worst;
}

int main(int argc, char **argv) {
  if (argc != 5) {
    fprintf(stderr, "usage: %s SCENE.ply CAMERA.txt OUT.rgba CAMERAS.json\n", argv[0]);
    return 2;
  }
  REQUIRE(srug_abi_version() == SRUG_ABI_VERSION);
  printf("srug %s, ABI %u\n", srug_version(), srug_abi_version());

  uint32_t w, h;
  float fx, fy, cx, cy, c2w[16], near_plane, far_plane, azimuth, elevation;
  FILE *cf = fopen(argv[2], "r");
  REQUIRE(cf != NULL);
  REQUIRE(fscanf(cf, "%u %u %f %f %f %f", &w, &h, &fx, &fy, &cx, &cy) == 6);
  for (int i = 0; i < 16; i++) REQUIRE(fscanf(cf, "%f", &c2w[i]) == 1);
  REQUIRE(fscanf(cf, "%f %f %f %f", &near_plane, &far_plane, &azimuth, &elevation) == 4);
  fclose(cf);

  srug_context *ctx = NULL;
  CHECK(srug_context_create(NULL, SRUG_CONTEXT_VALIDATION, &ctx));
  char name[256];
  CHECK(srug_context_device_name(ctx, name, sizeof name, NULL));
  printf("device: %s\n", name);

  srug_scene *scene = NULL;
  CHECK(srug_scene_from_file(ctx, argv[1], &scene));
  size_t count = 0;
  uint32_t materials = 0;
  CHECK(srug_scene_info(scene, &count, &materials));
  printf("scene: %zu Gaussians, materials %u\n", count, materials);
  REQUIRE(count > 0 && materials == 1);

  size_t ply_len = 0;
  unsigned char *ply = read_file(argv[1], &ply_len);
  srug_scene *from_memory = NULL;
  CHECK(srug_scene_from_memory(ctx, ply, ply_len, &from_memory));
  free(ply); /* the library copied it */

  uint32_t channels = (1u << SRUG_CHANNEL_DEPTH) | (1u << SRUG_CHANNEL_NORMAL);
  srug_renderer *r = NULL;
  CHECK(srug_renderer_create(ctx, w, h, channels, &r));
  CHECK(srug_renderer_set_camera(r, fx, fy, cx, cy, c2w, near_plane, far_plane));
  const float sun[3] = {3.14159265f, 3.14159265f, 3.14159265f};
  CHECK(srug_renderer_set_sun(r, azimuth, elevation, sun));
  CHECK(srug_renderer_set_environment(r, NULL, 0.0f, 1.0f));
  CHECK(srug_renderer_set_shadow(r, 2048, 50.0f, 0.8f)); /* the balanced preset's */
  CHECK(srug_renderer_set_shadow_geometry_bias(r, 3.0f, 0.0f));
  CHECK(srug_renderer_set_exposure(r, 0.0f, SRUG_TONE_MAP_ACES));
  CHECK(srug_renderer_render(r, scene));
  unsigned char *image = read_rgba8(r, w, h);

  FILE *out = fopen(argv[3], "wb");
  REQUIRE(out != NULL);
  REQUIRE(fwrite(image, 1, (size_t)w * h * 4, out) == (size_t)w * h * 4);
  fclose(out);

  /* Timings and memory. */
  size_t stages = 0;
  CHECK(srug_renderer_stage_count(r, &stages));
  REQUIRE(stages > 0);
  double total = 0.0;
  for (size_t i = 0; i < stages; i++) {
    char stage[128];
    double seconds = -1.0;
    CHECK(srug_renderer_stage(r, i, stage, sizeof stage, &seconds));
    REQUIRE(seconds >= 0.0 && stage[0] != 0);
    total += seconds;
  }
  printf("%zu GPU stages, %.1f ms\n", stages, total * 1e3);
  uint64_t current = 0, peak = 0;
  CHECK(srug_context_memory(ctx, &current, &peak));
  printf("GPU memory: %.1f MiB now, %.1f MiB peak\n", current / 1048576.0, peak / 1048576.0);
  REQUIRE(current > 0 && peak >= current);
  /* The buffers the frames freed are kept for reuse until released, within the peak. */
  uint64_t pooled = 0, fresh = 0, pooled_after = 1, fresh_after = 0;
  CHECK(srug_context_memory_pool(ctx, &pooled, &fresh));
  REQUIRE(pooled > 0 && current + pooled <= peak + (32u << 20) && fresh > 0);
  uint64_t released = 0, released_again = 1;
  CHECK(srug_context_release_pooled_memory(ctx, &released));
  CHECK(srug_context_release_pooled_memory(ctx, &released_again));
  printf("released %.1f MiB of pooled buffers\n", released / 1048576.0);
  REQUIRE(released == pooled && released_again == 0);
  CHECK(srug_context_memory_pool(ctx, &pooled_after, NULL));
  CHECK(srug_context_memory_pool(ctx, NULL, &fresh_after));
  REQUIRE(pooled_after == 0 && fresh_after == fresh);

  /* Channels: depth and normal were asked for, L_sun comes with a relit frame. */
  size_t pixels = (size_t)w * h;
  float *values = malloc(pixels * 3 * sizeof(float));
  REQUIRE(values != NULL);
  REQUIRE(srug_channel_components(SRUG_CHANNEL_NORMAL) == 3);
  CHECK(srug_renderer_read_channel(r, SRUG_CHANNEL_NORMAL, values, pixels * 3));
  for (size_t i = 0; i < pixels * 3; i++) REQUIRE(isfinite(values[i]));
  CHECK(srug_renderer_read_channel(r, SRUG_CHANNEL_DEPTH, values, pixels));
  size_t covered = 0;
  for (size_t i = 0; i < pixels; i++) {
    REQUIRE(isfinite(values[i]) && values[i] >= 0.0f);
    covered += values[i] > 0.0f;
  }
  REQUIRE(covered > pixels / 2);
  CHECK(srug_renderer_read_channel(r, SRUG_CHANNEL_SUN_LIGHT, values, pixels * 3));
  float brightest = 0.0f;
  for (size_t i = 0; i < pixels * 3; i++) {
    REQUIRE(isfinite(values[i]) && values[i] >= 0.0f);
    if (values[i] > brightest) brightest = values[i];
  }
  REQUIRE(brightest > 0.0f);

  /* The scene's own colour comes with a relit frame only when the mask asks: shading never
     reads it, so the relit image is the same bytes either way. */
  EXPECT(srug_renderer_read_channel(r, SRUG_CHANNEL_RGB, values, pixels * 3), SRUG_ERROR_WRONG_ORDER);
  srug_renderer *with_rgb = NULL;
  CHECK(srug_renderer_create(ctx, w, h, channels | (1u << SRUG_CHANNEL_RGB), &with_rgb));
  CHECK(srug_renderer_set_camera(with_rgb, fx, fy, cx, cy, c2w, near_plane, far_plane));
  CHECK(srug_renderer_set_sun(with_rgb, azimuth, elevation, sun));
  CHECK(srug_renderer_set_environment(with_rgb, NULL, 0.0f, 1.0f));
  CHECK(srug_renderer_render(with_rgb, scene));
  unsigned char *rgb_image = read_rgba8(with_rgb, w, h);
  REQUIRE(memcmp(rgb_image, image, pixels * 4) == 0);
  free(rgb_image);
  for (size_t i = 0; i < pixels * 3; i++) values[i] = NAN; /* sentinel */
  CHECK(srug_renderer_read_channel(with_rgb, SRUG_CHANNEL_RGB, values, pixels * 3));
  size_t coloured = 0;
  for (size_t i = 0; i < pixels * 3; i++) {
    REQUIRE(isfinite(values[i]) && values[i] >= 0.0f);
    coloured += values[i] > 0.0f;
  }
  REQUIRE(coloured > pixels);
  CHECK(srug_renderer_destroy(with_rgb));

  /* Linear float image: finite, alpha equals the RGBA8 alpha within rounding. */
  float *linear = malloc(pixels * 4 * sizeof(float));
  REQUIRE(linear != NULL);
  CHECK(srug_renderer_read_image(r, SRUG_FORMAT_RGBA32F_LINEAR, linear, pixels * 16, 0));
  for (size_t i = 0; i < pixels; i++) {
    for (int c = 0; c < 4; c++) REQUIRE(isfinite(linear[4 * i + c]));
    REQUIRE(fabsf(linear[4 * i + 3] * 255.0f - (float)image[4 * i + 3]) <= 0.5f);
  }
  free(linear);

  /* The scene parsed from memory renders the same image. */
  CHECK(srug_renderer_render(r, from_memory));
  unsigned char *again = read_rgba8(r, w, h);
  REQUIRE(memcmp(image, again, pixels * 4) == 0);
  free(again);

  /* Shadow-map reuse: the second render under the same sun skips the map's
     splat (fewer stages, less GPU time) and gives the same bytes. */
  size_t fresh_stages = 0, reused_stages = 0;
  CHECK(srug_renderer_set_shadow_map_reuse(r, true));
  CHECK(srug_renderer_render(r, scene));
  CHECK(srug_renderer_stage_count(r, &fresh_stages));
  CHECK(srug_renderer_render(r, scene));
  CHECK(srug_renderer_stage_count(r, &reused_stages));
  again = read_rgba8(r, w, h);
  REQUIRE(memcmp(image, again, pixels * 4) == 0);
  free(again);
  printf("shadow-map reuse: %zu stages, then %zu\n", fresh_stages, reused_stages);
  /* Without reuse the map served one frame, so it was culled to its receivers: one stage more. */
  REQUIRE(fresh_stages + 1 == stages && reused_stages < fresh_stages);
  /* A different scene handle gets its own map. */
  CHECK(srug_renderer_render(r, from_memory));
  CHECK(srug_renderer_stage_count(r, &reused_stages));
  REQUIRE(reused_stages == fresh_stages);
  CHECK(srug_renderer_set_shadow_map_reuse(r, false));
  CHECK(srug_renderer_render(r, scene));
  CHECK(srug_renderer_stage_count(r, &reused_stages));
  REQUIRE(reused_stages == stages);

  /* 8-pixel tiles: the same frame up to rounding, which can
     flip a few shadow-edge pixels (the sigmoid test is steep). */
  CHECK(srug_renderer_set_tile(r, 8));
  CHECK(srug_renderer_render(r, scene));
  again = read_rgba8(r, w, h);
  double tile_mean = 0.0;
  size_t tile_far = 0;
  for (size_t i = 0; i < pixels * 4; i++) {
    int d = abs((int)again[i] - (int)image[i]);
    tile_mean += d;
    tile_far += d > 8;
  }
  tile_mean /= (double)(pixels * 4);
  printf("tile 8: mean |tile 8 - tile 16| = %.3f of 255, %zu of %zu values off by more than 8\n", tile_mean,
         tile_far, pixels * 4);
  REQUIRE(tile_mean < 0.5 && tile_far * 200 < pixels * 4);
  free(again);
  CHECK(srug_renderer_set_tile(r, 16));

  /* Presets: balanced is the renderer's default (same bytes); fast renders at half
     size and reads back resampled to the full size, close to the balanced frame. */
  CHECK(srug_renderer_set_preset(r, "balanced"));
  CHECK(srug_renderer_render(r, scene));
  again = read_rgba8(r, w, h);
  REQUIRE(memcmp(image, again, pixels * 4) == 0);
  free(again);
  CHECK(srug_renderer_set_preset(r, "fast"));
  CHECK(srug_renderer_render(r, scene));
  unsigned char *fast = read_rgba8(r, w, h);
  double fast_diff = 0.0;
  for (size_t i = 0; i < pixels * 4; i++) fast_diff += fabs((double)fast[i] - (double)image[i]);
  fast_diff /= (double)(pixels * 4);
  printf("fast preset: mean |fast - balanced| = %.2f of 255\n", fast_diff);
  REQUIRE(fast_diff > 0.0 && fast_diff < 20.0);
  free(fast);
  CHECK(srug_renderer_read_channel(r, SRUG_CHANNEL_DEPTH, values, pixels));
  for (size_t i = 0; i < pixels; i++) REQUIRE(isfinite(values[i]) && values[i] >= 0.0f);
  CHECK(srug_renderer_set_preset(r, "balanced"));

  /* Surface depths (the presets') move the depth channel against the splats' centre depths
     (each pixel's ray against the splat's plane). */
  CHECK(srug_renderer_set_surface_depth(r, false));
  CHECK(srug_renderer_render(r, scene));
  float *centre_depth = malloc(pixels * sizeof(float)), *plane_depth = malloc(pixels * sizeof(float));
  REQUIRE(centre_depth != NULL && plane_depth != NULL);
  CHECK(srug_renderer_read_channel(r, SRUG_CHANNEL_DEPTH, centre_depth, pixels));
  CHECK(srug_renderer_set_surface_depth(r, true));
  CHECK(srug_renderer_render(r, scene));
  CHECK(srug_renderer_read_channel(r, SRUG_CHANNEL_DEPTH, plane_depth, pixels));
  size_t moved = 0;
  for (size_t i = 0; i < pixels; i++) {
    REQUIRE(isfinite(plane_depth[i]) && plane_depth[i] >= 0.0f);
    moved += fabsf(plane_depth[i] - centre_depth[i]) > 1e-3f;
  }
  printf("surface depth: %zu of %zu depths moved\n", moved, pixels);
  REQUIRE(moved * 100 > pixels);
  /* The map's occluders with surface depths too: another frame, close to the default. */
  CHECK(srug_renderer_set_map_surface_depth(r, true));
  double map_diff = rerender_difference(r, scene, image, w, h);
  printf("map surface depths: mean |map - default| = %.3f of 255\n", map_diff);
  REQUIRE(map_diff > 0.0 && map_diff < 2.0);
  CHECK(srug_renderer_set_map_surface_depth(r, false));
  /* The map and the receivers read at one half's coverage (the presets': 0.6 and 0.45):
     shadows a little wider, fewer receivers; out of (0, 1) refused, the setting kept. */
  CHECK(srug_renderer_set_shadow_coverage(r, 0.5f, 0.5f));
  double coverage_diff = rerender_difference(r, scene, image, w, h);
  printf("shadow coverage 0.5, 0.5: mean |0.5 - default| = %.3f of 255\n", coverage_diff);
  REQUIRE(coverage_diff > 0.0 && coverage_diff < 2.0);
  EXPECT(srug_renderer_set_shadow_coverage(r, 1.0f, 0.45f), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_shadow_coverage(r, 0.6f, NAN), SRUG_ERROR_INVALID_ARGUMENT);
  REQUIRE(rerender_difference(r, scene, image, w, h) == coverage_diff);
  CHECK(srug_renderer_set_shadow_coverage(r, 0.6f, 0.45f));
  /* A shadow map fitted to the view: the same scene, finer texels, close to the default. */
  CHECK(srug_renderer_set_shadow_fit(r, SRUG_SHADOW_FIT_VIEW));
  double fit_diff = rerender_difference(r, scene, image, w, h);
  printf("view-fitted shadow map: mean |view - scene| = %.3f of 255\n", fit_diff);
  REQUIRE(fit_diff > 0.0 && fit_diff < 5.0);
  /* Cascaded shadow maps: finer texels near the camera, the same shadows elsewhere. */
  CHECK(srug_renderer_set_shadow_fit(r, SRUG_SHADOW_FIT_CASCADES));
  CHECK(srug_renderer_set_shadow_cascades(r, 2));
  double cascade_diff = rerender_difference(r, scene, image, w, h);
  printf("cascaded shadow maps: mean |cascades - scene| = %.3f of 255\n", cascade_diff);
  REQUIRE(cascade_diff > 0.0 && cascade_diff < 5.0);
  CHECK(srug_renderer_set_shadow_fit(r, SRUG_SHADOW_FIT_SCENE));
  /* The paper's depth test instead of percentage-closer filtering: shadow edges move
     by under a texel, so the frames are close but not equal. */
  CHECK(srug_renderer_set_shadow_filter(r, SRUG_SHADOW_FILTER_DEPTH));
  double filter_diff = rerender_difference(r, scene, image, w, h);
  printf("depth-test shadows: mean |depth - pcf| = %.3f of 255\n", filter_diff);
  REQUIRE(filter_diff > 0.0 && filter_diff < 2.0);
  CHECK(srug_renderer_set_shadow_filter(r, SRUG_SHADOW_FILTER_PCF));
  /* A shadow map splatted only where the frame looks: the same frame, byte for byte. */
  CHECK(srug_renderer_set_shadow_cull(r, true));
  CHECK(srug_renderer_render(r, scene));
  unsigned char *culled = read_rgba8(r, w, h);
  REQUIRE(memcmp(culled, image, pixels * 4) == 0);
  free(culled);
  CHECK(srug_renderer_set_shadow_cull(r, false));
  printf("culled shadow map: the same frame\n");
  /* A host's mesh 5 m in front of the camera over the left half hides the splats there;
     the right half, where the host has nothing (camera z 0), keeps them. */
  CHECK(srug_renderer_render(r, scene));
  float *open_alpha = malloc(pixels * sizeof(float)), *hidden_alpha = malloc(pixels * sizeof(float));
  float *host = malloc(pixels * sizeof(float));
  REQUIRE(open_alpha != NULL && hidden_alpha != NULL && host != NULL);
  CHECK(srug_renderer_read_channel(r, SRUG_CHANNEL_ALPHA, open_alpha, pixels));
  for (size_t i = 0; i < pixels; i++) host[i] = (i % w) < w / 2 ? 5.0f : 0.0f;
  CHECK(srug_renderer_set_host_depth(r, host, pixels, SRUG_DEPTH_CAMERA_Z, 0.0f, 0.0f));
  CHECK(srug_renderer_render(r, scene));
  CHECK(srug_renderer_read_channel(r, SRUG_CHANNEL_ALPHA, hidden_alpha, pixels));
  size_t lost = 0, kept = 0, right = 0;
  for (size_t i = 0; i < pixels; i++) {
    if ((i % w) < w / 2) {
      lost += hidden_alpha[i] + 0.05f < open_alpha[i];
    } else {
      right++;
      kept += hidden_alpha[i] == open_alpha[i];
    }
  }
  printf("host depth: %zu left-half pixels lost coverage; %zu of %zu right-half pixels unchanged\n", lost, kept,
         right);
  REQUIRE(lost * 4 > pixels / 2 && kept == right);
  /* Backgrounds: where nothing covers a pixel its linear radiance is the background exactly; black
     makes the radiance premultiplied, to composite over the host's colour. */
  float *lin_bg = malloc(pixels * 16);
  REQUIRE(lin_bg != NULL);
  const float black[3] = {0.0f, 0.0f, 0.0f}, red[3] = {1.0f, 0.0f, 0.0f};
  const float *backgrounds[2] = {black, red};
  for (int b = 0; b < 2; b++) {
    CHECK(srug_renderer_set_background(r, backgrounds[b]));
    CHECK(srug_renderer_render(r, scene));
    CHECK(srug_renderer_read_image(r, SRUG_FORMAT_RGBA32F_LINEAR, lin_bg, pixels * 16, 0));
    size_t empty = 0;
    for (size_t i = 0; i < pixels; i++) {
      if (lin_bg[4 * i + 3] != 0.0f) continue;
      empty++;
      for (int c = 0; c < 3; c++) REQUIRE(lin_bg[4 * i + c] == backgrounds[b][c]);
    }
    printf("background %d: %zu uncovered pixels show it exactly\n", b, empty);
    REQUIRE(empty > pixels / 10);
  }
  const float negative[3] = {-1.0f, 0.0f, 0.0f};
  EXPECT(srug_renderer_set_background(r, negative), SRUG_ERROR_INVALID_ARGUMENT);
  CHECK(srug_renderer_set_background(r, NULL));
  free(lin_bg);
  EXPECT(srug_renderer_set_host_depth(r, host, pixels - 1, SRUG_DEPTH_CAMERA_Z, 0.0f, 0.0f),
         SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_host_depth(r, host, pixels, 9, 0.0f, 0.0f), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_host_depth(r, host, pixels, SRUG_DEPTH_VULKAN, 0.0f, 100.0f),
         SRUG_ERROR_INVALID_ARGUMENT); /* near must be > 0 */
  host[7] = NAN;
  EXPECT(srug_renderer_set_host_depth(r, host, pixels, SRUG_DEPTH_CAMERA_Z, 0.0f, 0.0f),
         SRUG_ERROR_INVALID_ARGUMENT);
  CHECK(srug_renderer_set_host_depth(r, NULL, 0, SRUG_DEPTH_CAMERA_Z, 0.0f, 0.0f));
  CHECK(srug_renderer_render(r, scene));
  CHECK(srug_renderer_read_channel(r, SRUG_CHANNEL_ALPHA, hidden_alpha, pixels));
  REQUIRE(memcmp(hidden_alpha, open_alpha, pixels * sizeof(float)) == 0);
  free(open_alpha);
  free(hidden_alpha);
  free(host);
  free(centre_depth);
  free(plane_depth);

  /* The same camera as OpenGL view and projection matrices. */
  float view[16] = {0}, proj[16] = {0};
  /* world-to-camera (GL) = diag(1, -1, -1) * inverse(c2w). */
  for (int row = 0; row < 3; row++) {
    float sign = row == 0 ? 1.0f : -1.0f;
    float t = 0.0f;
    for (int col = 0; col < 3; col++) {
      view[col * 4 + row] = sign * c2w[row * 4 + col]; /* transpose of the rotation */
      t -= c2w[row * 4 + col] * c2w[12 + col];
    }
    view[12 + row] = sign * t;
  }
  view[15] = 1.0f;
  proj[0] = 2.0f * fx / (float)w;
  proj[5] = 2.0f * fy / (float)h;
  proj[8] = 1.0f - 2.0f * cx / (float)w;
  proj[9] = 2.0f * cy / (float)h - 1.0f;
  proj[10] = -(far_plane + near_plane) / (far_plane - near_plane);
  proj[11] = -1.0f;
  proj[14] = -2.0f * far_plane * near_plane / (far_plane - near_plane);
  CHECK(srug_renderer_set_camera_matrices(r, view, proj));
  CHECK(srug_renderer_render(r, scene));
  unsigned char *from_matrices = read_rgba8(r, w, h);
  int diff = max_difference(image, from_matrices, pixels * 4);
  printf("camera from OpenGL matrices: max difference %d/255\n", diff);
  REQUIRE(diff <= 2); /* the matrices go through float rounding */
  free(from_matrices);
  CHECK(srug_renderer_set_camera(r, fx, fy, cx, cy, c2w, near_plane, far_plane));

  /* Any COLMAP camera model: PINHOLE is the same camera; OPENCV distorts it;
     EQUIRECTANGULAR sees all around. */
  const double pinhole[4] = {fx, fy, cx, cy};
  CHECK(srug_renderer_set_camera_model(r, "PINHOLE", pinhole, 4, c2w, near_plane, far_plane));
  CHECK(srug_renderer_render(r, scene));
  unsigned char *from_model = read_rgba8(r, w, h);
  REQUIRE(memcmp(from_model, image, pixels * 4) == 0);
  free(from_model);
  const double opencv[8] = {fx, fy, cx, cy, -0.2, 0.05, 0.001, -0.002};
  CHECK(srug_renderer_set_camera_model(r, "OPENCV", opencv, 8, c2w, near_plane, far_plane));
  CHECK(srug_renderer_render(r, scene));
  unsigned char *distorted = read_rgba8(r, w, h);
  diff = max_difference(image, distorted, pixels * 4);
  printf("OPENCV lens: max difference from the pinhole %d/255\n", diff);
  REQUIRE(diff > 32);
  free(distorted);
  const double panorama[2] = {(double)w, (double)h};
  CHECK(srug_renderer_set_camera_model(r, "EQUIRECTANGULAR", panorama, 2, c2w, near_plane, far_plane));
  CHECK(srug_renderer_render(r, scene));
  float *pano_alpha = malloc(pixels * sizeof(float));
  REQUIRE(pano_alpha != NULL);
  CHECK(srug_renderer_read_channel(r, SRUG_CHANNEL_ALPHA, pano_alpha, pixels));
  size_t pano_covered = 0;
  for (size_t i = 0; i < pixels; i++) pano_covered += pano_alpha[i] > 0.5f;
  printf("EQUIRECTANGULAR: %zu of %zu pixels covered\n", pano_covered, pixels);
  REQUIRE(pano_covered > pixels / 3);
  free(pano_alpha);
  EXPECT(srug_renderer_set_camera_model(r, "NO_SUCH_MODEL", opencv, 8, c2w, near_plane, far_plane),
         SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_camera_model(r, "OPENCV", opencv, 7, c2w, near_plane, far_plane),
         SRUG_ERROR_INVALID_ARGUMENT);
  /* A cameras file (here the demo's cameras.json): camera 0 is the camera above. */
  size_t camera_count = 0;
  CHECK(srug_renderer_set_camera_from_file(r, argv[4], 0, &camera_count));
  printf("cameras file: %zu cameras\n", camera_count);
  REQUIRE(camera_count >= 2);
  CHECK(srug_renderer_render(r, scene));
  unsigned char *from_file = read_rgba8(r, w, h);
  diff = max_difference(image, from_file, pixels * 4);
  printf("camera 0 from the file: max difference %d/255\n", diff);
  REQUIRE(diff <= 2); /* the file holds decimal floats */
  free(from_file);
  EXPECT(srug_renderer_set_camera_from_file(r, argv[4], camera_count, NULL), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_camera_from_file(r, argv[1], 0, NULL), SRUG_ERROR_INVALID_ARGUMENT); /* not cameras */
  CHECK(srug_renderer_set_camera(r, fx, fy, cx, cy, c2w, near_plane, far_plane));

  /* Two threads, two renderers, one context, rendering at once. */
  srug_renderer *r2 = NULL;
  CHECK(srug_renderer_create(ctx, w, h, 0, &r2));
  CHECK(srug_renderer_set_camera(r2, fx, fy, cx, cy, c2w, near_plane, far_plane));
  CHECK(srug_renderer_set_sun(r2, azimuth, elevation, sun));
  job jobs[2] = {{r, scene, SRUG_ERROR_PANIC}, {r2, from_memory, SRUG_ERROR_PANIC}};
  pthread_t threads[2];
  for (int i = 0; i < 2; i++) REQUIRE(pthread_create(&threads[i], NULL, render_job, &jobs[i]) == 0);
  for (int i = 0; i < 2; i++) REQUIRE(pthread_join(threads[i], NULL) == 0);
  REQUIRE(jobs[0].status == SRUG_OK && jobs[1].status == SRUG_OK);
  unsigned char *a = read_rgba8(r, w, h), *b = read_rgba8(r2, w, h);
  REQUIRE(memcmp(a, image, pixels * 4) == 0 && memcmp(b, image, pixels * 4) == 0);
  free(a);
  free(b);
  CHECK(srug_renderer_destroy(r2));

  /* A training step's shadow pass: forward V, backward with dL/dV = 1 per pixel. */
  float *visibility = malloc(pixels * sizeof(float));
  float *dl_dv = malloc(pixels * sizeof(float));
  REQUIRE(visibility != NULL && dl_dv != NULL);
  CHECK(srug_renderer_shadow_forward(r, scene, visibility, pixels));
  size_t shadowed = 0;
  for (size_t i = 0; i < pixels; i++) {
    REQUIRE(visibility[i] >= 0.0f && visibility[i] <= 1.0f);
    shadowed += visibility[i] < 0.5f;
    dl_dv[i] = 1.0f;
  }
  printf("shadow forward: %zu of %zu pixels shadowed\n", shadowed, pixels);
  REQUIRE(shadowed > 0);
  float *g = calloc(count * 11, sizeof(float));
  REQUIRE(g != NULL);
  srug_gaussian_gradients grads = {g, g + 3 * count, g + 6 * count, g + 10 * count, count};
  CHECK(srug_renderer_shadow_backward(r, scene, dl_dv, pixels, &grads));
  size_t nonzero = 0;
  for (size_t i = 0; i < count * 11; i++) {
    REQUIRE(isfinite(g[i]));
    nonzero += g[i] != 0.0f;
  }
  printf("shadow backward: %zu of %zu gradient entries non-zero\n", nonzero, count * 11);
  REQUIRE(nonzero > 0);

  /* Moving the Gaussians invalidates the forward pass. */
  float *means = calloc(count * 3, sizeof(float)), *ls = calloc(count * 3, sizeof(float));
  float *rot = calloc(count * 4, sizeof(float)), *op = calloc(count, sizeof(float));
  REQUIRE(means && ls && rot && op);
  for (size_t i = 0; i < count; i++) {
    means[3 * i] = (float)(i % 100);
    ls[3 * i] = ls[3 * i + 1] = ls[3 * i + 2] = -1.0f;
    rot[4 * i] = 1.0f;
  }
  CHECK(srug_scene_set_gaussians(from_memory, means, ls, rot, op, count));
  CHECK(srug_renderer_shadow_forward(r, from_memory, visibility, pixels));
  CHECK(srug_scene_set_gaussians(from_memory, means, ls, rot, op, count));
  EXPECT(srug_renderer_shadow_backward(r, from_memory, dl_dv, pixels, &grads), SRUG_ERROR_WRONG_ORDER);
  free(means);
  free(ls);
  free(rot);
  free(op);

  expect_no_validation_messages(ctx);
  pin_loaded_modules();
  free(g);
  free(dl_dv);
  free(visibility);
  free(values);
  free(image);
  CHECK(srug_renderer_destroy(r));
  CHECK(srug_scene_destroy(from_memory));
  CHECK(srug_scene_destroy(scene));
  CHECK(srug_context_destroy(ctx));
  size_t live = 1;
  CHECK(srug_live_handle_count(&live));
  REQUIRE(live == 0);
  printf("render: ok\n");
  return 0;
}
