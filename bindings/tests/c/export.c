/* A host that keeps srug on a Vulkan device of its own (srug_context_create)
 * and imports srug's frames into its own device: srug_renderer_export_image
 * gives the memory of an image at the renderer's size as an opaque fd; the
 * host creates an identical image with that memory on its device (another
 * VkInstance and VkDevice), and for each of a few frames of a moving camera
 * srug renders into it (srug_renderer_render_to_exported) and the host
 * acquires it from VK_QUEUE_FAMILY_EXTERNAL, copies it out, releases it back,
 * and compares it with srug_renderer_read_image's RGBA32F frame. Both
 * messengers hear nothing; AddressSanitizer runs it. Without
 * VK_KHR_external_memory_fd the export is refused with SRUG_ERROR_UNSUPPORTED. */
#define _GNU_SOURCE /* dl_iterate_phdr, RTLD_NODELETE */
#include <math.h>

#include "vkhost.h"

enum { W = 176, H = 48, FRAMES = 4 };

/* Moves the imported image between VK_QUEUE_FAMILY_EXTERNAL and the host's family (GENERAL throughout). */
static void ownership(VkCommandBuffer cmd, VkImage image, uint32_t from, uint32_t to, VkAccessFlags src,
                      VkAccessFlags dst) {
  VkImageMemoryBarrier b = {.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER,
                            .srcAccessMask = src,
                            .dstAccessMask = dst,
                            .oldLayout = VK_IMAGE_LAYOUT_GENERAL,
                            .newLayout = VK_IMAGE_LAYOUT_GENERAL,
                            .srcQueueFamilyIndex = from,
                            .dstQueueFamilyIndex = to,
                            .image = image,
                            .subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1}};
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, 0, NULL, 0,
                       NULL, 1, &b);
}

int main(void) {
  srug_context *ctx = NULL;
  srug_scene *scene = NULL;
  srug_renderer *r = NULL;
  CHECK(srug_context_create(NULL, SRUG_CONTEXT_VALIDATION, &ctx));
  CHECK(srug_scene_create_demo(ctx, 20000, 7, &scene));
  CHECK(srug_renderer_create(ctx, W, H, 0, &r));
  const float sun[3] = {3.14159265f, 3.14159265f, 3.14159265f};
  CHECK(srug_renderer_set_sun(r, 260.0f, 50.0f, sun));
  CHECK(srug_renderer_set_shadow_map_reuse(r, true));

  printf("refusals:\n");
  EXPECT(srug_renderer_render_to_exported(r, scene), SRUG_ERROR_WRONG_ORDER);
  srug_exported_image exported;
  EXPECT(srug_renderer_export_image(r, VK_FORMAT_R8_UNORM, &exported), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_export_image(r, VK_FORMAT_D32_SFLOAT, &exported), SRUG_ERROR_INVALID_ARGUMENT);
  EXPECT(srug_renderer_export_image(r, VK_FORMAT_R32G32B32A32_SFLOAT, NULL), SRUG_ERROR_NULL_POINTER);
  srug_vulkan_image image = {0};
  srug_vulkan_targets targets = {.colour = &image};
  EXPECT(srug_renderer_render_to_vulkan(r, scene, &targets), SRUG_ERROR_WRONG_ORDER);
  srug_status status = srug_renderer_export_image(r, VK_FORMAT_R32G32B32A32_SFLOAT, &exported);
  if (status == SRUG_ERROR_UNSUPPORTED) {
    print_last_error("export: skipped");
    CHECK(srug_renderer_destroy(r));
    CHECK(srug_scene_destroy(scene));
    CHECK(srug_context_destroy(ctx));
    return 0;
  }
  CHECK(status);
  REQUIRE(exported.fd >= 0 && exported.width == W && exported.height == H);
  /* Semaphore export: lavapipe lacks VK_KHR_external_semaphore_fd, so it is refused by name there. */
  int semaphore_fd = -1;
  status = srug_renderer_export_semaphore(r, &semaphore_fd);
  if (status == SRUG_OK) {
    printf("semaphore exported\n");
  } else {
    char m[512] = {0};
    srug_last_error(m, sizeof m, NULL);
    REQUIRE(status == SRUG_ERROR_UNSUPPORTED && strstr(m, "VK_KHR_external_semaphore_fd") != NULL);
    printf("  %-28s %s\n", srug_status_name(status), m);
  }

  /* The host's own instance and device, on the same GPU and driver. */
  VkDebugUtilsMessengerEXT messenger;
  VkInstance instance = make_instance(&messenger);
  Gpu g = make_device(instance);
  REQUIRE(g.external_memory_fd);
  VkPhysicalDeviceIDProperties ids = {.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ID_PROPERTIES};
  VkPhysicalDeviceProperties2 props = {.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2, .pNext = &ids};
  vkGetPhysicalDeviceProperties2(g.physical, &props);
  REQUIRE(memcmp(ids.deviceUUID, exported.device_uuid, 16) == 0);
  REQUIRE(memcmp(ids.driverUUID, exported.driver_uuid, 16) == 0);
  /* With an exported semaphore, the host's reads wait on srug's signal through it. */
  VkSemaphore frame_done = VK_NULL_HANDLE;
  if (semaphore_fd >= 0) {
    REQUIRE(g.external_semaphore_fd);
    VkSemaphoreCreateInfo sci = {.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
    VK(vkCreateSemaphore(g.device, &sci, NULL, &frame_done));
    PFN_vkImportSemaphoreFdKHR import_fd =
        (PFN_vkImportSemaphoreFdKHR)vkGetDeviceProcAddr(g.device, "vkImportSemaphoreFdKHR");
    REQUIRE(import_fd != NULL);
    VkImportSemaphoreFdInfoKHR info = {.sType = VK_STRUCTURE_TYPE_IMPORT_SEMAPHORE_FD_INFO_KHR,
                                       .semaphore = frame_done,
                                       .handleType = VK_EXTERNAL_SEMAPHORE_HANDLE_TYPE_OPAQUE_FD_BIT,
                                       .fd = semaphore_fd};
    VK(import_fd(g.device, &info));
  }

  /* The imported image: created as srug's, bound to the exported memory (Vulkan now owns the fd). */
  VkExternalMemoryImageCreateInfo external = {.sType = VK_STRUCTURE_TYPE_EXTERNAL_MEMORY_IMAGE_CREATE_INFO,
                                              .handleTypes = VK_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD_BIT};
  VkImageCreateInfo ci = {.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO,
                          .pNext = &external,
                          .imageType = VK_IMAGE_TYPE_2D,
                          .format = (VkFormat)exported.format,
                          .extent = {exported.width, exported.height, 1},
                          .mipLevels = 1,
                          .arrayLayers = 1,
                          .samples = VK_SAMPLE_COUNT_1_BIT,
                          .tiling = VK_IMAGE_TILING_OPTIMAL,
                          .usage = exported.usage,
                          .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED};
  VkImage imported;
  VK(vkCreateImage(g.device, &ci, NULL, &imported));
  VkMemoryRequirements req;
  vkGetImageMemoryRequirements(g.device, imported, &req);
  VkImportMemoryFdInfoKHR import = {.sType = VK_STRUCTURE_TYPE_IMPORT_MEMORY_FD_INFO_KHR,
                                    .handleType = VK_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD_BIT,
                                    .fd = exported.fd};
  VkMemoryDedicatedAllocateInfo dedicated = {.sType = VK_STRUCTURE_TYPE_MEMORY_DEDICATED_ALLOCATE_INFO,
                                             .pNext = &import,
                                             .image = imported};
  VkMemoryAllocateInfo ai = {.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
                             .pNext = &dedicated,
                             .allocationSize = exported.allocation_size,
                             .memoryTypeIndex = memory_type(&g, req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT)};
  VkDeviceMemory memory;
  VK(vkAllocateMemory(g.device, &ai, NULL, &memory));
  VK(vkBindImageMemory(g.device, imported, memory, 0));

  const size_t bytes = (size_t)W * H * 16;
  Mapped readback = make_mapped(&g, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT);
  float *expected = malloc(bytes);
  REQUIRE(expected != NULL);
  for (int frame = 0; frame < FRAMES; frame++) {
    const float eye[3] = {-40.0f + 2.0f * (float)frame, -2.0f, 1.6f}, target[3] = {eye[0] + 30.0f, -2.0f, 1.3f};
    const float up[3] = {0.0f, 0.0f, 1.0f};
    CHECK(srug_renderer_set_camera_look_at(r, eye, target, up, 90.0f));
    CHECK(srug_renderer_render_to_exported(r, scene));
    /* srug's call returned with its work done: the host acquires, copies, releases. */
    VkCommandBuffer cmd = begin(&g);
    ownership(cmd, imported, VK_QUEUE_FAMILY_EXTERNAL, g.family, 0, VK_ACCESS_TRANSFER_READ_BIT);
    VkBufferImageCopy region = {.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1}, .imageExtent = {W, H, 1}};
    vkCmdCopyImageToBuffer(cmd, imported, VK_IMAGE_LAYOUT_GENERAL, readback.buffer, 1, &region);
    ownership(cmd, imported, g.family, VK_QUEUE_FAMILY_EXTERNAL, VK_ACCESS_TRANSFER_READ_BIT, 0);
    VkMemoryBarrier host = {.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                            .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                            .dstAccessMask = VK_ACCESS_HOST_READ_BIT};
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &host, 0, NULL, 0,
                         NULL);
    submit(&g, cmd, frame_done, VK_NULL_HANDLE);
    CHECK(srug_renderer_read_image(r, SRUG_FORMAT_RGBA32F_LINEAR, expected, bytes, 0));
    const float *got = readback.data;
    int lit = 0;
    for (int i = 0; i < W * H * 4; i++) {
      if (fabsf(got[i] - expected[i]) > 1e-6f) {
        fprintf(stderr, "frame %d: value %d is %g, srug read %g\n", frame, i, got[i], expected[i]);
        exit(1);
      }
      if (i % 4 == 0 && got[i] > 0.0f) lit++;
    }
    REQUIRE(lit > W * H / 4);
  }
  printf("export: %d frames imported into the host's device equal srug's\n", FRAMES);
  expect_no_validation_messages(ctx);
  pin_loaded_modules();
  CHECK(srug_renderer_destroy(r));
  CHECK(srug_scene_destroy(scene));
  CHECK(srug_context_destroy(ctx));

  VK(vkDeviceWaitIdle(g.device));
  free(expected);
  free_mapped(&g, &readback);
  if (frame_done != VK_NULL_HANDLE) vkDestroySemaphore(g.device, frame_done, NULL);
  vkDestroyImage(g.device, imported, NULL);
  vkFreeMemory(g.device, memory, NULL);
  vkDestroyCommandPool(g.device, g.pool, NULL);
  vkDestroyDevice(g.device, NULL);
  printf("host messenger heard %d message(s)\n", heard);
  REQUIRE(heard == 0);
  destroy_instance(instance, messenger);
  return 0;
}
