/* A host application's Vulkan plumbing for the C tests: an instance with
 * validation and synchronization validation and its own messenger (counting
 * what it hears), a device with srug's required features, images and
 * host-visible buffers with their own memory, one-off submissions. */
#ifndef SRUG_TEST_VKHOST_H
#define SRUG_TEST_VKHOST_H

#include <vulkan/vulkan.h>

#include "check.h"

static int heard = 0;

static inline VKAPI_ATTR VkBool32 VKAPI_CALL hear(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                           VkDebugUtilsMessageTypeFlagsEXT type,
                                           const VkDebugUtilsMessengerCallbackDataEXT *data, void *user) {
  (void)type;
  (void)user;
  if (severity & (VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT)) {
    heard++;
    fprintf(stderr, "host messenger: %s\n", data->pMessage);
  }
  return VK_FALSE;
}

#define VK(call)                                                                      \
  do {                                                                                \
    VkResult r_ = (call);                                                             \
    if (r_ != VK_SUCCESS) {                                                           \
      fprintf(stderr, "%s:%d: %s returned %d\n", __FILE__, __LINE__, #call, (int)r_); \
      exit(1);                                                                        \
    }                                                                                 \
  } while (0)

typedef struct {
  VkPhysicalDevice physical;
  VkDevice device;
  VkQueue queue;
  uint32_t family;
  VkCommandPool pool;
  int external_memory_fd;    /* VK_KHR_external_memory_fd enabled */
  int external_semaphore_fd; /* VK_KHR_external_semaphore_fd enabled */
} Gpu;

static inline uint32_t memory_type(const Gpu *g, uint32_t bits, VkMemoryPropertyFlags flags) {
  VkPhysicalDeviceMemoryProperties props;
  vkGetPhysicalDeviceMemoryProperties(g->physical, &props);
  for (uint32_t i = 0; i < props.memoryTypeCount; i++)
    if ((bits & (1u << i)) && (props.memoryTypes[i].propertyFlags & flags) == flags) return i;
  REQUIRE(!"no suitable memory type");
  return 0;
}

typedef struct {
  VkImage image;
  VkDeviceMemory memory;
  VkImageView view;
} Image;

static inline Image make_image(const Gpu *g, VkFormat format, uint32_t width, uint32_t height, VkImageUsageFlags usage,
                        VkImageAspectFlags aspect) {
  Image i;
  VkImageCreateInfo ci = {.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO,
                          .imageType = VK_IMAGE_TYPE_2D,
                          .format = format,
                          .extent = {width, height, 1},
                          .mipLevels = 1,
                          .arrayLayers = 1,
                          .samples = VK_SAMPLE_COUNT_1_BIT,
                          .tiling = VK_IMAGE_TILING_OPTIMAL,
                          .usage = usage,
                          .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED};
  VK(vkCreateImage(g->device, &ci, NULL, &i.image));
  VkMemoryRequirements req;
  vkGetImageMemoryRequirements(g->device, i.image, &req);
  VkMemoryAllocateInfo ai = {.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
                             .allocationSize = req.size,
                             .memoryTypeIndex = memory_type(g, req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT)};
  VK(vkAllocateMemory(g->device, &ai, NULL, &i.memory));
  VK(vkBindImageMemory(g->device, i.image, i.memory, 0));
  VkImageViewCreateInfo vi = {.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO,
                              .image = i.image,
                              .viewType = VK_IMAGE_VIEW_TYPE_2D,
                              .format = format,
                              .subresourceRange = {aspect, 0, 1, 0, 1}};
  VK(vkCreateImageView(g->device, &vi, NULL, &i.view));
  return i;
}

static inline void free_image(const Gpu *g, Image *i) {
  vkDestroyImageView(g->device, i->view, NULL);
  vkDestroyImage(g->device, i->image, NULL);
  vkFreeMemory(g->device, i->memory, NULL);
}

typedef struct {
  VkBuffer buffer;
  VkDeviceMemory memory;
  void *data;
} Mapped;

static inline Mapped make_mapped(const Gpu *g, VkDeviceSize size, VkBufferUsageFlags usage) {
  Mapped m;
  VkBufferCreateInfo ci = {.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO, .size = size, .usage = usage};
  VK(vkCreateBuffer(g->device, &ci, NULL, &m.buffer));
  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(g->device, m.buffer, &req);
  VkMemoryAllocateInfo ai = {
      .sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
      .allocationSize = req.size,
      .memoryTypeIndex = memory_type(g, req.memoryTypeBits,
                                     VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT)};
  VK(vkAllocateMemory(g->device, &ai, NULL, &m.memory));
  VK(vkBindBufferMemory(g->device, m.buffer, m.memory, 0));
  VK(vkMapMemory(g->device, m.memory, 0, size, 0, &m.data));
  return m;
}

static inline void free_mapped(const Gpu *g, Mapped *m) {
  vkUnmapMemory(g->device, m->memory);
  vkDestroyBuffer(g->device, m->buffer, NULL);
  vkFreeMemory(g->device, m->memory, NULL);
}

static inline void barrier(VkCommandBuffer cmd, VkImage image, VkImageAspectFlags aspect, VkImageLayout from,
                    VkImageLayout to, VkAccessFlags src_access, VkAccessFlags dst_access) {
  VkImageMemoryBarrier b = {.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER,
                            .srcAccessMask = src_access,
                            .dstAccessMask = dst_access,
                            .oldLayout = from,
                            .newLayout = to,
                            .srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
                            .dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
                            .image = image,
                            .subresourceRange = {aspect, 0, 1, 0, 1}};
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, 0, NULL, 0,
                       NULL, 1, &b);
}

static inline VkCommandBuffer begin(const Gpu *g) {
  VkCommandBufferAllocateInfo ai = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
                                    .commandPool = g->pool,
                                    .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
                                    .commandBufferCount = 1};
  VkCommandBuffer cmd;
  VK(vkAllocateCommandBuffers(g->device, &ai, &cmd));
  VkCommandBufferBeginInfo bi = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
                                 .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT};
  VK(vkBeginCommandBuffer(cmd, &bi));
  return cmd;
}

/* Ends, submits (waiting on `wait` at every stage, signalling `signal`; either may be NULL) and waits. */
static inline void submit(const Gpu *g, VkCommandBuffer cmd, VkSemaphore wait, VkSemaphore signal) {
  VK(vkEndCommandBuffer(cmd));
  VkPipelineStageFlags stage = VK_PIPELINE_STAGE_ALL_COMMANDS_BIT;
  VkSubmitInfo si = {.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO,
                     .waitSemaphoreCount = wait ? 1 : 0,
                     .pWaitSemaphores = &wait,
                     .pWaitDstStageMask = &stage,
                     .commandBufferCount = 1,
                     .pCommandBuffers = &cmd,
                     .signalSemaphoreCount = signal ? 1 : 0,
                     .pSignalSemaphores = &signal};
  VkFenceCreateInfo fi = {.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  VkFence fence;
  VK(vkCreateFence(g->device, &fi, NULL, &fence));
  VK(vkQueueSubmit(g->queue, 1, &si, fence));
  VK(vkWaitForFences(g->device, 1, &fence, VK_TRUE, UINT64_MAX));
  vkDestroyFence(g->device, fence, NULL);
  vkFreeCommandBuffers(g->device, g->pool, 1, &cmd);
}

static inline VkInstance make_instance(VkDebugUtilsMessengerEXT *messenger) {
  const char *layers[] = {"VK_LAYER_KHRONOS_validation"};
  const char *extensions[] = {VK_EXT_DEBUG_UTILS_EXTENSION_NAME, VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME};
  VkValidationFeatureEnableEXT sync = VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT;
  VkValidationFeaturesEXT features = {.sType = VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT,
                                      .enabledValidationFeatureCount = 1,
                                      .pEnabledValidationFeatures = &sync};
  VkApplicationInfo app = {.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO, .apiVersion = VK_API_VERSION_1_2};
  VkInstanceCreateInfo ici = {.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO,
                              .pNext = &features,
                              .pApplicationInfo = &app,
                              .enabledLayerCount = 1,
                              .ppEnabledLayerNames = layers,
                              .enabledExtensionCount = 2,
                              .ppEnabledExtensionNames = extensions};
  VkInstance instance;
  VK(vkCreateInstance(&ici, NULL, &instance));
  PFN_vkCreateDebugUtilsMessengerEXT create =
      (PFN_vkCreateDebugUtilsMessengerEXT)vkGetInstanceProcAddr(instance, "vkCreateDebugUtilsMessengerEXT");
  REQUIRE(create != NULL);
  VkDebugUtilsMessengerCreateInfoEXT mci = {
      .sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT,
      .messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT,
      .messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT,
      .pfnUserCallback = hear};
  VK(create(instance, &mci, NULL, messenger));
  return instance;
}

static inline Gpu make_device(VkInstance instance) {
  Gpu g;
  uint32_t count = 1;
  VkResult listed = vkEnumeratePhysicalDevices(instance, &count, &g.physical);
  REQUIRE((listed == VK_SUCCESS || listed == VK_INCOMPLETE) && count == 1);
  uint32_t families = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(g.physical, &families, NULL);
  VkQueueFamilyProperties props[16];
  families = families < 16 ? families : 16;
  vkGetPhysicalDeviceQueueFamilyProperties(g.physical, &families, props);
  VkQueueFlags needed = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
  g.family = 0;
  while (g.family < families && (props[g.family].queueFlags & needed) != needed) g.family++;
  REQUIRE(g.family < families);
  float priority = 1.0f;
  VkDeviceQueueCreateInfo qci = {.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO,
                                 .queueFamilyIndex = g.family,
                                 .queueCount = 1,
                                 .pQueuePriorities = &priority};
  VkPhysicalDeviceVulkan12Features v12 = {.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES,
                                          .bufferDeviceAddress = VK_TRUE};
  VkPhysicalDeviceFeatures2 f2 = {.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2, .pNext = &v12};
  f2.features.shaderInt64 = VK_TRUE;
  /* What srug exports is imported through VK_KHR_external_{memory,semaphore}_fd, where offered. */
  uint32_t offered = 0;
  VK(vkEnumerateDeviceExtensionProperties(g.physical, NULL, &offered, NULL));
  VkExtensionProperties *extensions = calloc(offered ? offered : 1, sizeof *extensions);
  REQUIRE(extensions != NULL);
  VK(vkEnumerateDeviceExtensionProperties(g.physical, NULL, &offered, extensions));
  const char *wanted[2] = {VK_KHR_EXTERNAL_MEMORY_FD_EXTENSION_NAME, VK_KHR_EXTERNAL_SEMAPHORE_FD_EXTENSION_NAME};
  const char *enabled[2];
  uint32_t enabled_count = 0;
  g.external_memory_fd = g.external_semaphore_fd = 0;
  for (int w = 0; w < 2; w++)
    for (uint32_t i = 0; i < offered; i++)
      if (strcmp(extensions[i].extensionName, wanted[w]) == 0) {
        enabled[enabled_count++] = wanted[w];
        *(w == 0 ? &g.external_memory_fd : &g.external_semaphore_fd) = 1;
      }
  free(extensions);
  VkDeviceCreateInfo dci = {.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO,
                            .pNext = &f2,
                            .queueCreateInfoCount = 1,
                            .pQueueCreateInfos = &qci,
                            .enabledExtensionCount = enabled_count,
                            .ppEnabledExtensionNames = enabled};
  VK(vkCreateDevice(g.physical, &dci, NULL, &g.device));
  vkGetDeviceQueue(g.device, g.family, 0, &g.queue);
  VkCommandPoolCreateInfo pci = {.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO,
                                 .flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT,
                                 .queueFamilyIndex = g.family};
  VK(vkCreateCommandPool(g.device, &pci, NULL, &g.pool));
  return g;
}

/* Destroys the messenger and the instance (the device first, by the caller). */
static inline void destroy_instance(VkInstance instance, VkDebugUtilsMessengerEXT messenger) {
  PFN_vkDestroyDebugUtilsMessengerEXT destroy =
      (PFN_vkDestroyDebugUtilsMessengerEXT)vkGetInstanceProcAddr(instance, "vkDestroyDebugUtilsMessengerEXT");
  REQUIRE(destroy != NULL);
  destroy(instance, messenger, NULL);
  vkDestroyInstance(instance, NULL);
}

#endif
