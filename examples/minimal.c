/* The smallest complete use of srug's C API: render the demo city under an
 * evening sun into an RGBA8 buffer. Build (see docs/embedding.md):
 *   cc -std=c11 -I bindings/include examples/minimal.c -L target/release -lsrug_c -o minimal
 */
#include <stdio.h>
#include <stdlib.h>

#include "srug.h"

static int fail(srug_status status) {
  char message[512];
  srug_last_error(message, sizeof message, NULL);
  fprintf(stderr, "%s: %s\n", srug_status_name(status), message);
  return 1;
}

int main(void) {
  enum { W = 352, H = 96 };
  const float eye[3] = {-40.0f, -2.0f, 1.6f}, target[3] = {0.0f, -2.0f, 1.2f}, up[3] = {0.0f, 0.0f, 1.0f};
  const float sun[3] = {3.14f, 3.14f, 3.14f};
  srug_context *ctx = NULL;
  srug_scene *scene = NULL;
  srug_renderer *renderer = NULL;
  unsigned char *pixels = malloc((size_t)W * H * 4);
  srug_status s;
  if (pixels == NULL) return 1;

  if ((s = srug_context_create(NULL, 0, &ctx)) != SRUG_OK ||
      (s = srug_scene_create_demo(ctx, 5000, 7, &scene)) != SRUG_OK ||
      (s = srug_renderer_create(ctx, W, H, 0, &renderer)) != SRUG_OK ||
      (s = srug_renderer_set_camera_look_at(renderer, eye, target, up, 90.0f)) != SRUG_OK ||
      (s = srug_renderer_set_sun(renderer, 260.0f, 20.0f, sun)) != SRUG_OK ||
      (s = srug_renderer_render(renderer, scene)) != SRUG_OK ||
      (s = srug_renderer_read_image(renderer, SRUG_FORMAT_RGBA8_SRGB, pixels, (size_t)W * H * 4, 0)) != SRUG_OK) {
    int code = fail(s);
    srug_renderer_destroy(renderer);
    srug_scene_destroy(scene);
    srug_context_destroy(ctx);
    free(pixels);
    return code;
  }
  printf("srug %s: rendered %dx%d, centre pixel %u %u %u\n", srug_version(), W, H,
         pixels[(H / 2 * W + W / 2) * 4], pixels[(H / 2 * W + W / 2) * 4 + 1], pixels[(H / 2 * W + W / 2) * 4 + 2]);
  srug_renderer_destroy(renderer);
  srug_scene_destroy(scene);
  srug_context_destroy(ctx);
  free(pixels);
  return 0;
}
