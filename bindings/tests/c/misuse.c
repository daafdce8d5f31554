/* Every misuse the C API must answer with a status and a message, not a crash:
 * NULL pointers, destroyed and foreign handles, short buffers, bad values,
 * corrupt input, and calls in the wrong order.
 *
 * usage: misuse SCENE.ply */
#define _GNU_SOURCE /* dl_iterate_phdr, RTLD_NODELETE */
#include <math.h>
#include <stdint.h>
#include <unistd.h>

#include "check.h"

int main(int argc, char **argv) {
  if (argc != 2) {
    fprintf(stderr, "usage: %s SCENE.ply\n", argv[0]);
    return 2;
  }
  const char *ply = argv[1];
  srug_context *ctx = NULL, *other = NULL;
  srug_scene *scene = NULL, *foreign_scene = NULL;
  srug_renderer *r = NULL;

  printf("last error before any failure:\n");
  size_t n = 99;
  CHECK(srug_last_error(NULL, 0, &n));
  REQUIRE(n == 0);

  printf("NULL pointers:\n");
  EXPECT(srug_context_create(NULL, 0, NULL), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_scene_info(NULL, &n, NULL), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_renderer_render(NULL, NULL), SRUG_ERROR_NULL_POINTER);
  CHECK(srug_context_destroy(NULL)); /* like free(NULL) */
  CHECK(srug_scene_destroy(NULL));

  printf("bad arguments:\n");
  EXPECT(srug_context_create(NULL, 0x80, &ctx), SRUG_ERROR_INVALID_ARGUMENT);
  REQUIRE(ctx == NULL); /* nothing written on failure */
  CHECK(srug_context_create(NULL, SRUG_CONTEXT_VALIDATION, &ctx));
  srug_context *none = NULL;
  EXPECT(srug_context_create("no such device name", SRUG_CONTEXT_VALIDATION, &none), SRUG_ERROR_NO_DEVICE);
  REQUIRE(none == NULL);
  CHECK(srug_context_create(NULL, SRUG_CONTEXT_VALIDATION, &other));
  EXPECT(srug_context_memory(ctx, NULL, NULL), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_context_memory_pool(ctx, NULL, NULL), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_context_memory_pool(NULL, NULL, NULL), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_context_release_pooled_memory(NULL, NULL), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_scene_from_file(ctx, "/nonexistent/scene.ply", &scene), SRUG_ERROR_IO);
  EXPECT(srug_scene_from_file(ctx, NULL, &scene), SRUG_ERROR_NULL_POINTER);
  const unsigned char corrupt[] = "ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nend_header\n\x01\x02";
  EXPECT(srug_scene_from_memory(ctx, corrupt, sizeof corrupt - 1, &scene), SRUG_ERROR_BAD_FILE);
  EXPECT(srug_scene_from_memory(ctx, NULL, 10, &scene), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_scene_create_demo(ctx, 10, 1, &scene), SRUG_ERROR_INVALID_ARGUMENT);
  REQUIRE(scene == NULL);
  EXPECT(srug_environment_from_file(ctx, "/nonexistent/sky.exr", NULL), SRUG_ERROR_NULL_POINTER);
  {
    /* A malformed environment map has its own status, distinct from a malformed scene. */
    char bad_env[] = "/tmp/srug-misuse-XXXXXX.hdr";
    int fd = mkstemps(bad_env, 4);
    REQUIRE(fd >= 0);
    REQUIRE(write(fd, "not a radiance file", 19) == 19);
    close(fd);
    srug_environment *bad = NULL;
    EXPECT(srug_environment_from_file(ctx, bad_env, &bad), SRUG_ERROR_BAD_ENVIRONMENT);
    REQUIRE(bad == NULL);
    unlink(bad_env);
  }
  srug_environment *env = NULL;
  EXPECT(srug_environment_from_file(ctx, "/nonexistent/sky.exr", &env), SRUG_ERROR_IO);
  EXPECT(srug_environment_sky(ctx, NAN, &env), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_create(ctx, 0, 10, 0, &r), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_create(ctx, 10, 100000, 0, &r), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_create(ctx, 10, 10, 1u << 20, &r), SRUG_ERROR_INVALID_ARGUMENT);
  REQUIRE(r == NULL);

  CHECK(srug_scene_from_file(ctx, ply, &scene));
  CHECK(srug_scene_create_demo(other, 1000, 3, &foreign_scene));
  CHECK(srug_renderer_create(ctx, 64, 48, 0, &r));

  printf("calls in the wrong order:\n");
  EXPECT(srug_renderer_render(r, scene), SRUG_ERROR_WRONG_ORDER);
  unsigned char pixels[64 * 48 * 4];
  EXPECT(srug_renderer_read_image(r, SRUG_FORMAT_RGBA8_SRGB, pixels, sizeof pixels, 0), SRUG_ERROR_WRONG_ORDER);
  size_t stages = 0;
  EXPECT(srug_renderer_stage_count(r, &stages), SRUG_ERROR_WRONG_ORDER);
  const float eye[3] = {0.0f, -30.0f, 20.0f}, target[3] = {0.0f, 0.0f, 5.0f}, up[3] = {0.0f, 0.0f, 1.0f};
  CHECK(srug_renderer_set_camera_look_at(r, eye, target, up, 70.0f));
  float v[64 * 48] = {0};
  EXPECT(srug_renderer_shadow_forward(r, scene, v, 64 * 48), SRUG_ERROR_WRONG_ORDER); /* no sun */
  const float white[3] = {1.0f, 1.0f, 1.0f};
  CHECK(srug_renderer_set_sun(r, 200.0f, 40.0f, white));
  size_t count = 0;
  CHECK(srug_scene_info(scene, &count, NULL));
  float *g = calloc(count * 11, sizeof(float));
  REQUIRE(g != NULL);
  srug_gaussian_gradients grads = {g, g + 3 * count, g + 6 * count, g + 10 * count, count};
  EXPECT(srug_renderer_shadow_backward(r, scene, v, 64 * 48, &grads), SRUG_ERROR_WRONG_ORDER);
  EXPECT(srug_context_destroy(ctx), SRUG_ERROR_WRONG_ORDER); /* objects still alive */

  printf("bad values:\n");
  float c2w[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  c2w[13] = NAN;
  EXPECT(srug_renderer_set_camera(r, 50, 50, 32, 24, c2w, 0.01f, 100.0f), SRUG_ERROR_INVALID_ARGUMENT);
  c2w[13] = 0.0f;
  c2w[0] = 2.0f; /* not a rotation */
  EXPECT(srug_renderer_set_camera(r, 50, 50, 32, 24, c2w, 0.01f, 100.0f), SRUG_ERROR_INVALID_ARGUMENT);
  c2w[0] = 1.0f;
  EXPECT(srug_renderer_set_camera(r, 50, 50, 32, 24, c2w, 1.0f, 0.5f), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_camera(r, -5, 50, 32, 24, c2w, 0.01f, 100.0f), SRUG_ERROR_INVALID_ARGUMENT);
  const double folding[8] = {50, 50, 32, 24, -0.9, 0.0, 0.0, 0.0}; /* k1 = −0.9 folds inside the image */
  EXPECT(srug_renderer_set_camera_model(r, "OPENCV", folding, 8, c2w, 0.01f, 100.0f), SRUG_ERROR_INVALID_ARGUMENT);
  const double nan_params[4] = {50, NAN, 32, 24};
  EXPECT(srug_renderer_set_camera_model(r, "PINHOLE", nan_params, 4, c2w, 0.01f, 100.0f), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_camera_model(r, "PINHOLE", NULL, 4, c2w, 0.01f, 100.0f), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_renderer_set_camera_model(r, NULL, folding, 4, c2w, 0.01f, 100.0f), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_renderer_set_camera_from_file(r, NULL, 0, NULL), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_renderer_set_camera_from_file(r, "/nonexistent/cameras.json", 0, NULL), SRUG_ERROR_IO);
  float ortho[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  EXPECT(srug_renderer_set_camera_matrices(r, c2w, ortho), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_sun(r, 0.0f, 100.0f, white), SRUG_ERROR_INVALID_ARGUMENT);
  const float negative[3] = {1.0f, -1.0f, 1.0f};
  EXPECT(srug_renderer_set_sun(r, 0.0f, 30.0f, negative), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_shadow(r, 0, 50.0f, 0.5f), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_shadow(r, 1024, NAN, 0.5f), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_preset(r, "fastest"), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_preset(r, NULL), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_renderer_set_exposure(r, 0.0f, 77), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_tile(r, 12), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_tile(r, 0), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_environment(r, NULL, 0.0f, -1.0f), SRUG_ERROR_INVALID_ARGUMENT);
  float *means = calloc(count * 3, sizeof(float)), *ls = calloc(count * 3, sizeof(float));
  float *rot = calloc(count * 4, sizeof(float)), *op = calloc(count, sizeof(float));
  REQUIRE(means && ls && rot && op);
  rot[4 * 2 + 1] = INFINITY;
  EXPECT(srug_scene_set_gaussians(scene, means, ls, rot, op, count), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_scene_set_gaussians(scene, means, ls, rot, op, count + 1), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_scene_set_gaussians(scene, means, NULL, rot, op, count), SRUG_ERROR_NULL_POINTER);

  printf("short buffers and unknown enumerators:\n");
  CHECK(srug_renderer_render(r, scene));
  EXPECT(srug_renderer_read_image(r, SRUG_FORMAT_RGBA8_SRGB, pixels, sizeof pixels - 1, 0), SRUG_ERROR_BUFFER_TOO_SMALL);
  EXPECT(srug_renderer_read_image(r, SRUG_FORMAT_RGBA32F_LINEAR, pixels, sizeof pixels, 0), SRUG_ERROR_BUFFER_TOO_SMALL);
  EXPECT(srug_renderer_read_image(r, SRUG_FORMAT_RGBA8_SRGB, pixels, sizeof pixels, 64 * 4 - 1), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_read_image(r, 9, pixels, sizeof pixels, 0), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_read_image(r, SRUG_FORMAT_RGBA8_SRGB, NULL, sizeof pixels, 0), SRUG_ERROR_NULL_POINTER);
  CHECK(srug_renderer_read_image(r, SRUG_FORMAT_RGBA8_SRGB, pixels, sizeof pixels, 0));
  EXPECT(srug_renderer_read_channel(r, SRUG_CHANNEL_VISIBILITY, v, 64 * 48), SRUG_ERROR_WRONG_ORDER); /* not rendered */
  EXPECT(srug_renderer_read_channel(r, 99, v, 64 * 48), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_read_channel(r, SRUG_CHANNEL_ALPHA, v, 64 * 48 - 1), SRUG_ERROR_BUFFER_TOO_SMALL);
  EXPECT(srug_renderer_read_channel(r, SRUG_CHANNEL_ALPHA, (float *)(pixels + 1), 64 * 48), SRUG_ERROR_INVALID_ARGUMENT); /* misaligned */
  CHECK(srug_renderer_stage_count(r, &stages));
  double seconds = 0.0;
  EXPECT(srug_renderer_stage(r, stages, NULL, 0, &seconds), SRUG_ERROR_INVALID_ARGUMENT);
  char tiny[4];
  EXPECT(srug_renderer_stage(r, 0, tiny, sizeof tiny, &seconds), SRUG_ERROR_BUFFER_TOO_SMALL);
  CHECK(srug_renderer_shadow_forward(r, scene, v, 64 * 48));
  srug_gaussian_gradients short_grads = grads;
  short_grads.count = count - 1;
  EXPECT(srug_renderer_shadow_backward(r, scene, v, 64 * 48, &short_grads), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_shadow_backward(r, scene, v, 64 * 48 - 1, &grads), SRUG_ERROR_BUFFER_TOO_SMALL);
  EXPECT(srug_renderer_shadow_backward(r, scene, v, 64 * 48, NULL), SRUG_ERROR_NULL_POINTER);

  printf("careless callers (issue 39):\n");
  EXPECT(srug_renderer_read_image(r, SRUG_FORMAT_RGBA8_SRGB, pixels, sizeof pixels, SIZE_MAX), SRUG_ERROR_INVALID_ARGUMENT);
  CHECK(srug_renderer_read_image(r, SRUG_FORMAT_RGBA8_SRGB, pixels, sizeof pixels, 0)); /* not poisoned */
  EXPECT(srug_renderer_set_shadow(r, 15, 50.0f, 0.5f), SRUG_ERROR_INVALID_ARGUMENT);   /* header: 16..=16384 */
  EXPECT(srug_renderer_set_shadow(r, 1024, 50.0f, -1.0f), SRUG_ERROR_INVALID_ARGUMENT); /* header: bias >= 0 */
  EXPECT(srug_renderer_set_shadow_geometry_bias(r, -1.0f, 0.0f), SRUG_ERROR_INVALID_ARGUMENT);  /* header: 0 to 100 */
  EXPECT(srug_renderer_set_shadow_geometry_bias(r, 3.0f, NAN), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_shadow_geometry_bias(NULL, 3.0f, 0.0f), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_renderer_set_surface_depth(NULL, true), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_renderer_set_shadow_fit(r, 7), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_shadow_fit(NULL, SRUG_SHADOW_FIT_VIEW), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_renderer_set_shadow_filter(r, 9), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_shadow_cascades(r, 1), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_shadow_cascades(r, 5), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_shadow_cascades(NULL, 3), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_renderer_set_shadow_filter(NULL, SRUG_SHADOW_FILTER_DEPTH), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_renderer_set_camera_look_at(r, eye, target, up, 1e-40f), SRUG_ERROR_INVALID_ARGUMENT);
  const float along[3] = {0.0f, 30.0f, -15.0f}; /* parallel to target - eye */
  EXPECT(srug_renderer_set_camera_look_at(r, eye, target, along, 70.0f), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_set_exposure(r, 1e30f, SRUG_TONE_MAP_ACES), SRUG_ERROR_INVALID_ARGUMENT);
  CHECK(srug_renderer_set_preset(r, "balanced"));
  {
    srug_scene *huge = NULL;
    EXPECT(srug_scene_create_demo(ctx, (size_t)1 << 40, 1, &huge), SRUG_ERROR_INVALID_ARGUMENT);
    EXPECT(srug_scene_create_demo(ctx, SIZE_MAX, 1, &huge), SRUG_ERROR_INVALID_ARGUMENT);
    REQUIRE(huge == NULL);
    size_t kept = 7;
    EXPECT(srug_context_take_validation_messages(ctx, &kept, NULL, 64), SRUG_ERROR_NULL_POINTER);
    REQUIRE(kept == 7); /* nothing written on failure */
    double untouched = -1.0;
    EXPECT(srug_renderer_stage(r, 0, NULL, 16, &untouched), SRUG_ERROR_NULL_POINTER);
    EXPECT(srug_renderer_stage(r, 0, tiny, sizeof tiny, &untouched), SRUG_ERROR_BUFFER_TOO_SMALL);
    REQUIRE(untouched == -1.0 && tiny[sizeof tiny - 1] == 0); /* a cut, terminated name; no time */
    char name[5];
    size_t name_len = 0;
    EXPECT(srug_context_device_name(ctx, name, sizeof name, &name_len), SRUG_ERROR_BUFFER_TOO_SMALL);
    REQUIRE(strlen(name) == sizeof name - 1 && name_len > sizeof name); /* the documented cut copy */
  }
  CHECK(srug_renderer_set_camera_look_at(r, eye, target, up, 70.0f));
  CHECK(srug_renderer_render(r, scene));

  printf("foreign and destroyed handles:\n");
  EXPECT(srug_renderer_render(r, foreign_scene), SRUG_ERROR_INVALID_ARGUMENT); /* another context */
  EXPECT(srug_renderer_render((srug_renderer *)scene, scene), SRUG_ERROR_INVALID_HANDLE);
  EXPECT(srug_scene_info((srug_scene *)(uintptr_t)0x1234, &count, NULL), SRUG_ERROR_INVALID_HANDLE);
  EXPECT(srug_scene_info((srug_scene *)&count, &count, NULL), SRUG_ERROR_INVALID_HANDLE); /* a real address */
  CHECK(srug_scene_destroy(foreign_scene));
  EXPECT(srug_scene_info(foreign_scene, &count, NULL), SRUG_ERROR_INVALID_HANDLE);
  EXPECT(srug_scene_destroy(foreign_scene), SRUG_ERROR_INVALID_HANDLE); /* double destroy */
  CHECK(srug_context_destroy(other));
  EXPECT(srug_scene_create_demo(other, 1000, 3, &foreign_scene), SRUG_ERROR_INVALID_HANDLE);

  printf("the last error is per thread and cut to the buffer:\n");
  EXPECT(srug_renderer_set_exposure(r, 0.0f, 77), SRUG_ERROR_INVALID_ARGUMENT);
  char cut[8];
  size_t full = 0;
  REQUIRE(srug_last_error(cut, sizeof cut, &full) == SRUG_ERROR_BUFFER_TOO_SMALL);
  REQUIRE(strlen(cut) == sizeof cut - 1 && full > sizeof cut);
  REQUIRE(strcmp(srug_status_name(4), "SRUG_ERROR_BUFFER_TOO_SMALL") == 0);
  REQUIRE(strcmp(srug_status_name(1000), "SRUG_UNKNOWN_STATUS") == 0);

  expect_no_validation_messages(ctx);
  pin_loaded_modules();
  free(means);
  free(ls);
  free(rot);
  free(op);
  free(g);
  CHECK(srug_renderer_destroy(r));
  EXPECT(srug_renderer_render(r, scene), SRUG_ERROR_INVALID_HANDLE); /* destroyed */
  CHECK(srug_scene_destroy(scene));
  CHECK(srug_context_destroy(ctx));
  size_t live = 1;
  CHECK(srug_live_handle_count(&live));
  REQUIRE(live == 0);
  printf("misuse: ok\n");
  return 0;
}
