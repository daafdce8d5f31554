/* A host application with its own Vulkan instance and device, as a game
 * engine has (validation with synchronization validation on, and its own
 * debug messenger), hands them to srug with srug_context_create_from_vulkan.
 * srug renders the demo city on the host's device exactly as on a device of
 * its own; once the context is destroyed the host uses and destroys its device,
 * and its messenger has heard nothing (a srug object left behind would be
 * reported at vkDestroyDevice). Also: missing features and bad arguments are
 * refused by name. */
#define _GNU_SOURCE /* dl_iterate_phdr, RTLD_NODELETE */
#include "vkhost.h"

enum { W = 176, H = 48 };

/* The demo city's street camera under a west-south-west sun, RGBA8. */
static unsigned char *render(srug_context *ctx) {
  srug_scene *scene = NULL;
  srug_renderer *r = NULL;
  CHECK(srug_scene_create_demo(ctx, 20000, 7, &scene));
  CHECK(srug_renderer_create(ctx, W, H, 0, &r));
  const float eye[3] = {-40.0f, -2.0f, 1.6f}, target[3] = {-10.0f, -2.0f, 1.3f}, up[3] = {0.0f, 0.0f, 1.0f};
  CHECK(srug_renderer_set_camera_look_at(r, eye, target, up, 90.0f));
  const float sun[3] = {3.14159265f, 3.14159265f, 3.14159265f};
  CHECK(srug_renderer_set_sun(r, 260.0f, 50.0f, sun));
  CHECK(srug_renderer_render(r, scene));
  unsigned char *pixels = malloc((size_t)W * H * 4);
  REQUIRE(pixels != NULL);
  CHECK(srug_renderer_read_image(r, SRUG_FORMAT_RGBA8_SRGB, pixels, (size_t)W * H * 4, 0));
  CHECK(srug_renderer_destroy(r));
  CHECK(srug_scene_destroy(scene));
  return pixels;
}

int main(void) {
  /* The frame on srug's own device. */
  srug_context *own = NULL;
  CHECK(srug_context_create(NULL, SRUG_CONTEXT_VALIDATION, &own));
  unsigned char *own_frame = render(own);
  expect_no_validation_messages(own);
  pin_loaded_modules();
  CHECK(srug_context_destroy(own));

  /* The host's instance, messenger and device. */
  VkDebugUtilsMessengerEXT messenger;
  VkInstance instance = make_instance(&messenger);
  uint32_t count = 1;
  VkPhysicalDevice physical;
  VkResult listed = vkEnumeratePhysicalDevices(instance, &count, &physical);
  REQUIRE((listed == VK_SUCCESS || listed == VK_INCOMPLETE) && count == 1);
  uint32_t families = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(physical, &families, NULL);
  VkQueueFamilyProperties props[16];
  families = families < 16 ? families : 16;
  vkGetPhysicalDeviceQueueFamilyProperties(physical, &families, props);
  uint32_t family = 0;
  while (family < families && !(props[family].queueFlags & VK_QUEUE_COMPUTE_BIT)) family++;
  REQUIRE(family < families);
  float priority = 1.0f;
  VkDeviceQueueCreateInfo qci = {.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO,
                                 .queueFamilyIndex = family,
                                 .queueCount = 1,
                                 .pQueuePriorities = &priority};
  VkPhysicalDeviceVulkan12Features v12 = {.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES,
                                          .bufferDeviceAddress = VK_TRUE};
  VkPhysicalDeviceFeatures2 f2 = {.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2, .pNext = &v12};
  f2.features.shaderInt64 = VK_TRUE;
  VkDeviceCreateInfo dci = {.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO,
                            .pNext = &f2,
                            .queueCreateInfoCount = 1,
                            .pQueueCreateInfos = &qci};
  VkDevice device;
  VK(vkCreateDevice(physical, &dci, NULL, &device));

  /* The host's loader entry point, passed as data (ISO C has no function-to-object pointer cast). */
  PFN_vkGetInstanceProcAddr gipa = vkGetInstanceProcAddr;
  void *gipa_data = NULL;
  memcpy(&gipa_data, &gipa, sizeof gipa_data);
  srug_vulkan_device vulkan = {
      .instance = (void *)instance,
      .physical_device = (void *)physical,
      .device = (void *)device,
      .queue_family = family,
      .queue_index = 0,
      .get_instance_proc_addr = gipa_data,
      .enabled_features = SRUG_VULKAN_FEATURE_BUFFER_DEVICE_ADDRESS | SRUG_VULKAN_FEATURE_SHADER_INT64,
  };

  printf("refusals:\n");
  srug_context *ctx = NULL;
  EXPECT(srug_context_create_from_vulkan(NULL, 0, &ctx), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_context_create_from_vulkan(&vulkan, 0, NULL), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_context_create_from_vulkan(&vulkan, 0x100, &ctx), SRUG_ERROR_INVALID_ARGUMENT);
  srug_vulkan_device lacking = vulkan;
  lacking.enabled_features = SRUG_VULKAN_FEATURE_SHADER_INT64;
  EXPECT(srug_context_create_from_vulkan(&lacking, 0, &ctx), SRUG_ERROR_NO_DEVICE);
  char message[1024] = {0};
  srug_last_error(message, sizeof message, NULL);
  REQUIRE(strstr(message, "bufferDeviceAddress") != NULL);
  /* A feature bit past SRUG_VULKAN_FEATURE_COMPUTE_FULL_SUBGROUPS (the last one) is refused by value. */
  srug_vulkan_device unknown = vulkan;
  unknown.enabled_features |= SRUG_VULKAN_FEATURE_COMPUTE_FULL_SUBGROUPS << 1;
  EXPECT(srug_context_create_from_vulkan(&unknown, 0, &ctx), SRUG_ERROR_INVALID_ARGUMENT);
  srug_last_error(message, sizeof message, NULL);
  REQUIRE(strstr(message, "unknown feature bits 0x40") != NULL);
  srug_vulkan_device wrong_queue = vulkan;
  wrong_queue.queue_index = props[family].queueCount; /* one past the family's queues */
  EXPECT(srug_context_create_from_vulkan(&wrong_queue, 0, &ctx), SRUG_ERROR_NO_DEVICE);
  srug_vulkan_device no_device = vulkan;
  no_device.device = NULL;
  EXPECT(srug_context_create_from_vulkan(&no_device, 0, &ctx), SRUG_ERROR_NULL_POINTER);

  /* srug on the host's device: the same frame, no validation message. */
  CHECK(srug_context_create_from_vulkan(&vulkan, SRUG_CONTEXT_VALIDATION, &ctx));
  unsigned char *host_frame = render(ctx);
  REQUIRE(memcmp(own_frame, host_frame, (size_t)W * H * 4) == 0);
  expect_no_validation_messages(ctx);
  CHECK(srug_context_destroy(ctx));

  /* The device is still the host's: it works, and destroying it reports nothing left behind. */
  VkBufferCreateInfo bci = {.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
                            .size = 256,
                            .usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT};
  VkBuffer buffer;
  VK(vkCreateBuffer(device, &bci, NULL, &buffer));
  vkDestroyBuffer(device, buffer, NULL);
  VK(vkDeviceWaitIdle(device));
  vkDestroyDevice(device, NULL);
  printf("host device: srug's frame equals its own device's; host messenger heard %d message(s)\n", heard);
  REQUIRE(heard == 0);
  destroy_instance(instance, messenger);
  free(own_frame);
  free(host_frame);
  return 0;
}
