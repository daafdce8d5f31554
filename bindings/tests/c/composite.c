/* A game-engine-like host: its own Vulkan instance (validation with
 * synchronization validation, its own messenger) and device, a colour image
 * (RGBA16F) and a depth image (D32) of its own, and a graphics pipeline that
 * rasterizes a triangle mesh (a wall receding across the street and a sign)
 * into them, lit by srug's sun (srug_renderer_get_sun). Each of FRAMES frames of a camera moving down the demo street:
 * the host draws its mesh (signalling a semaphore), srug renders the demo city
 * into the same images with srug_renderer_render_to_vulkan (waiting on it,
 * hiding splats behind the mesh, blending the rest over the mesh's colour,
 * keeping the nearer depth, signalling another), and the host reads the images
 * back. Checked per frame against a CPU reference of the same composite: the
 * splats through the host-memory path (srug_renderer_set_host_depth with the
 * mesh's depth read back, premultiplied RGBA32F) over the mesh's colour,
 * rgb + (1 - alpha) * mesh; PSNR >= 45 dB, the depth never farther than the
 * mesh's; no validation message, none at vkDestroyDevice; AddressSanitizer
 * with leak detection runs it. Argument: an optional path for the last
 * frame's composite as a PPM (display: clamped, sRGB-encoded). */
#define _GNU_SOURCE /* dl_iterate_phdr, RTLD_NODELETE */
#include <math.h>
#include <shaderc/shaderc.h>

#include "vkhost.h"

enum { W = 256, H = 96, FRAMES = 100 };
static const float NEAR = 0.1f, FAR = 400.0f;

static VkShaderModule compile(const Gpu *g, shaderc_compiler_t compiler, const char *source, shaderc_shader_kind kind,
                              const char *name) {
  shaderc_compilation_result_t res =
      shaderc_compile_into_spv(compiler, source, strlen(source), kind, name, "main", NULL);
  if (shaderc_result_get_compilation_status(res) != shaderc_compilation_status_success) {
    fprintf(stderr, "%s: %s\n", name, shaderc_result_get_error_message(res));
    exit(1);
  }
  size_t len = shaderc_result_get_length(res);
  uint32_t *words = malloc(len);
  REQUIRE(words != NULL);
  memcpy(words, shaderc_result_get_bytes(res), len);
  shaderc_result_release(res);
  VkShaderModuleCreateInfo ci = {.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO, .codeSize = len, .pCode = words};
  VkShaderModule module;
  VK(vkCreateShaderModule(g->device, &ci, NULL, &module));
  free(words);
  return module;
}

/* The mesh is lit by srug's sun (srug_renderer_get_sun): albedo / pi * radiance * max(n.l, 0),
 * srug's diffuse term, plus a little ambient; flat normals facing the camera. */
#define PUSH_BLOCK "layout(push_constant) uniform Push { mat4 clip; vec4 eye; vec4 sun_dir; vec4 sun_radiance; } push;\n"
static const char *VERTEX_SHADER =
    "#version 450\n"
    "layout(location = 0) in vec3 position;\n"
    "layout(location = 1) in vec3 colour;\n" PUSH_BLOCK
    "layout(location = 0) out vec3 v_colour;\n"
    "layout(location = 1) out vec3 v_world;\n"
    "void main() { gl_Position = push.clip * vec4(position, 1.0); v_colour = colour; v_world = position; }\n";

static const char *FRAGMENT_SHADER =
    "#version 450\n" PUSH_BLOCK
    "layout(location = 0) in vec3 v_colour;\n"
    "layout(location = 1) in vec3 v_world;\n"
    "layout(location = 0) out vec4 colour;\n"
    "void main() {\n"
    "  vec3 n = normalize(cross(dFdx(v_world), dFdy(v_world)));\n"
    "  if (dot(n, push.eye.xyz - v_world) < 0.0) n = -n;\n"
    "  vec3 lit = v_colour / 3.14159265 * push.sun_radiance.rgb * max(dot(n, push.sun_dir.xyz), 0.0);\n"
    "  colour = vec4(lit + 0.05 * v_colour, 1.0);\n"
    "}\n";

/* The push constants both stages read. */
typedef struct {
  float clip[16], eye[4], sun_dir[4], sun_radiance[4];
} Push;

/* The mesh, in world coordinates (z up): a wall from 6 m to 26 m ahead,
 * receding from the left of the street to its right, and a sign near the camera. */
static const float MESH[][6] = {
    {-34.0f, 3.5f, 0.0f, 0.8f, 0.3f, 0.2f},  {-14.0f, -6.0f, 0.0f, 0.2f, 0.3f, 0.8f},
    {-14.0f, -6.0f, 7.0f, 0.9f, 0.9f, 0.9f}, {-34.0f, 3.5f, 0.0f, 0.8f, 0.3f, 0.2f},
    {-14.0f, -6.0f, 7.0f, 0.9f, 0.9f, 0.9f}, {-34.0f, 3.5f, 7.0f, 0.3f, 0.8f, 0.3f},
    {-36.0f, -4.5f, 0.2f, 1.0f, 0.9f, 0.1f}, {-36.0f, -3.0f, 0.2f, 1.0f, 0.9f, 0.1f},
    {-36.0f, -3.75f, 2.5f, 1.0f, 0.5f, 0.0f},
};
enum { VERTICES = sizeof MESH / sizeof MESH[0] };

/* Column-major 4x4 helpers. */
static void mul(float out[16], const float a[16], const float b[16]) {
  float r[16];
  for (int c = 0; c < 4; c++)
    for (int row = 0; row < 4; row++) {
      float s = 0.0f;
      for (int k = 0; k < 4; k++) s += a[k * 4 + row] * b[c * 4 + k];
      r[c * 4 + row] = s;
    }
  memcpy(out, r, sizeof r);
}

/* gluLookAt and gluPerspective (OpenGL conventions). */
static void look_at(float v[16], const float eye[3], const float target[3], const float up[3]) {
  float f[3] = {target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]};
  float n = sqrtf(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
  for (int i = 0; i < 3; i++) f[i] /= n;
  float s[3] = {f[1] * up[2] - f[2] * up[1], f[2] * up[0] - f[0] * up[2], f[0] * up[1] - f[1] * up[0]};
  n = sqrtf(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
  for (int i = 0; i < 3; i++) s[i] /= n;
  float u[3] = {s[1] * f[2] - s[2] * f[1], s[2] * f[0] - s[0] * f[2], s[0] * f[1] - s[1] * f[0]};
  const float m[16] = {s[0], u[0], -f[0], 0, s[1], u[1], -f[1], 0, s[2], u[2], -f[2], 0,
                       -(s[0] * eye[0] + s[1] * eye[1] + s[2] * eye[2]),
                       -(u[0] * eye[0] + u[1] * eye[1] + u[2] * eye[2]),
                       f[0] * eye[0] + f[1] * eye[1] + f[2] * eye[2], 1};
  memcpy(v, m, sizeof m);
}

static void perspective(float p[16], float fovy_degrees, float aspect, float near, float far) {
  float t = 1.0f / tanf(fovy_degrees * 3.14159265f / 360.0f);
  const float m[16] = {t / aspect, 0, 0, 0, 0, t, 0, 0, 0, 0, (far + near) / (near - far), -1,
                       0, 0, 2.0f * far * near / (near - far), 0};
  memcpy(p, m, sizeof m);
}

static float half_to_float(uint16_t h) {
  uint32_t sign = (uint32_t)(h >> 15) << 31, exponent = (h >> 10) & 31, mantissa = h & 1023;
  float magnitude;
  if (exponent == 0)
    magnitude = ldexpf((float)mantissa, -24);
  else if (exponent == 31)
    magnitude = mantissa ? NAN : INFINITY;
  else
    magnitude = ldexpf((float)(mantissa | 1024), (int)exponent - 25);
  return sign ? -magnitude : magnitude;
}

/* Copies the colour and depth images (in TRANSFER_SRC_OPTIMAL) into `out`: colour first, then depth. */
static void copy_out(VkCommandBuffer cmd, const Image *colour, const Image *depth, const Mapped *out) {
  VkBufferImageCopy c = {.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1}, .imageExtent = {W, H, 1}};
  vkCmdCopyImageToBuffer(cmd, colour->image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, out->buffer, 1, &c);
  VkBufferImageCopy d = {.bufferOffset = (VkDeviceSize)W * H * 8,
                         .imageSubresource = {VK_IMAGE_ASPECT_DEPTH_BIT, 0, 0, 1},
                         .imageExtent = {W, H, 1}};
  vkCmdCopyImageToBuffer(cmd, depth->image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, out->buffer, 1, &d);
  VkMemoryBarrier host = {.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                          .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                          .dstAccessMask = VK_ACCESS_HOST_READ_BIT};
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &host, 0, NULL, 0,
                       NULL);
}

typedef struct {
  VkRenderPass pass;
  VkFramebuffer framebuffer;
  VkPipelineLayout layout;
  VkPipeline pipeline;
} Raster;

static Raster make_raster(const Gpu *g, const Image *colour, const Image *depth) {
  Raster r;
  VkAttachmentDescription attachments[2] = {
      {.format = VK_FORMAT_R16G16B16A16_SFLOAT,
       .samples = VK_SAMPLE_COUNT_1_BIT,
       .loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR,
       .storeOp = VK_ATTACHMENT_STORE_OP_STORE,
       .stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
       .stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
       .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED,
       .finalLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL},
      {.format = VK_FORMAT_D32_SFLOAT,
       .samples = VK_SAMPLE_COUNT_1_BIT,
       .loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR,
       .storeOp = VK_ATTACHMENT_STORE_OP_STORE,
       .stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
       .stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
       .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED,
       .finalLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL}};
  VkAttachmentReference colour_ref = {0, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
  VkAttachmentReference depth_ref = {1, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
  VkSubpassDescription subpass = {.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS,
                                  .colorAttachmentCount = 1,
                                  .pColorAttachments = &colour_ref,
                                  .pDepthStencilAttachment = &depth_ref};
  /* The last frame's reads and srug's writes come before this frame's clears and draws. */
  VkPipelineStageFlags attachment_stages = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT |
                                           VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT |
                                           VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
  VkSubpassDependency dependencies[2] = {
      {.srcSubpass = VK_SUBPASS_EXTERNAL,
       .dstSubpass = 0,
       .srcStageMask = VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
       .dstStageMask = attachment_stages,
       .srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT,
       .dstAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT |
                        VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT},
      {.srcSubpass = 0,
       .dstSubpass = VK_SUBPASS_EXTERNAL,
       .srcStageMask = attachment_stages,
       .dstStageMask = VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
       .srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT,
       .dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT}};
  VkRenderPassCreateInfo rpi = {.sType = VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO,
                                .attachmentCount = 2,
                                .pAttachments = attachments,
                                .subpassCount = 1,
                                .pSubpasses = &subpass,
                                .dependencyCount = 2,
                                .pDependencies = dependencies};
  VK(vkCreateRenderPass(g->device, &rpi, NULL, &r.pass));
  VkImageView views[2] = {colour->view, depth->view};
  VkFramebufferCreateInfo fbi = {.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO,
                                 .renderPass = r.pass,
                                 .attachmentCount = 2,
                                 .pAttachments = views,
                                 .width = W,
                                 .height = H,
                                 .layers = 1};
  VK(vkCreateFramebuffer(g->device, &fbi, NULL, &r.framebuffer));
  VkPushConstantRange push = {VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof(Push)};
  VkPipelineLayoutCreateInfo pli = {.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
                                    .pushConstantRangeCount = 1,
                                    .pPushConstantRanges = &push};
  VK(vkCreatePipelineLayout(g->device, &pli, NULL, &r.layout));
  shaderc_compiler_t compiler = shaderc_compiler_initialize();
  REQUIRE(compiler != NULL);
  VkShaderModule vs = compile(g, compiler, VERTEX_SHADER, shaderc_vertex_shader, "mesh.vert");
  VkShaderModule fs = compile(g, compiler, FRAGMENT_SHADER, shaderc_fragment_shader, "mesh.frag");
  shaderc_compiler_release(compiler);
  VkPipelineShaderStageCreateInfo stages[2] = {
      {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
       .stage = VK_SHADER_STAGE_VERTEX_BIT,
       .module = vs,
       .pName = "main"},
      {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
       .stage = VK_SHADER_STAGE_FRAGMENT_BIT,
       .module = fs,
       .pName = "main"}};
  VkVertexInputBindingDescription binding = {0, sizeof MESH[0], VK_VERTEX_INPUT_RATE_VERTEX};
  VkVertexInputAttributeDescription attributes[2] = {{0, 0, VK_FORMAT_R32G32B32_SFLOAT, 0},
                                                     {1, 0, VK_FORMAT_R32G32B32_SFLOAT, 12}};
  VkPipelineVertexInputStateCreateInfo vertex_input = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO,
      .vertexBindingDescriptionCount = 1,
      .pVertexBindingDescriptions = &binding,
      .vertexAttributeDescriptionCount = 2,
      .pVertexAttributeDescriptions = attributes};
  VkPipelineInputAssemblyStateCreateInfo assembly = {.sType = VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO,
                                                     .topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST};
  VkViewport viewport = {0.0f, 0.0f, (float)W, (float)H, 0.0f, 1.0f};
  VkRect2D scissor = {{0, 0}, {W, H}};
  VkPipelineViewportStateCreateInfo viewport_state = {.sType = VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO,
                                                      .viewportCount = 1,
                                                      .pViewports = &viewport,
                                                      .scissorCount = 1,
                                                      .pScissors = &scissor};
  VkPipelineRasterizationStateCreateInfo raster = {.sType = VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO,
                                                   .polygonMode = VK_POLYGON_MODE_FILL,
                                                   .cullMode = VK_CULL_MODE_NONE,
                                                   .frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE,
                                                   .lineWidth = 1.0f};
  VkPipelineMultisampleStateCreateInfo multisample = {.sType = VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO,
                                                      .rasterizationSamples = VK_SAMPLE_COUNT_1_BIT};
  VkPipelineDepthStencilStateCreateInfo depth_state = {.sType =
                                                           VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO,
                                                       .depthTestEnable = VK_TRUE,
                                                       .depthWriteEnable = VK_TRUE,
                                                       .depthCompareOp = VK_COMPARE_OP_LESS};
  VkPipelineColorBlendAttachmentState blend_attachment = {.colorWriteMask = 0xf};
  VkPipelineColorBlendStateCreateInfo blend = {.sType = VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO,
                                               .attachmentCount = 1,
                                               .pAttachments = &blend_attachment};
  VkGraphicsPipelineCreateInfo gpi = {.sType = VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO,
                                      .stageCount = 2,
                                      .pStages = stages,
                                      .pVertexInputState = &vertex_input,
                                      .pInputAssemblyState = &assembly,
                                      .pViewportState = &viewport_state,
                                      .pRasterizationState = &raster,
                                      .pMultisampleState = &multisample,
                                      .pDepthStencilState = &depth_state,
                                      .pColorBlendState = &blend,
                                      .layout = r.layout,
                                      .renderPass = r.pass};
  VK(vkCreateGraphicsPipelines(g->device, VK_NULL_HANDLE, 1, &gpi, NULL, &r.pipeline));
  vkDestroyShaderModule(g->device, vs, NULL);
  vkDestroyShaderModule(g->device, fs, NULL);
  return r;
}

static void write_ppm(const char *path, const float *rgba) {
  FILE *f = fopen(path, "wb");
  REQUIRE(f != NULL);
  fprintf(f, "P6\n%d %d\n255\n", W, H);
  for (int p = 0; p < W * H; p++)
    for (int c = 0; c < 3; c++) {
      float v = fminf(fmaxf(rgba[4 * p + c], 0.0f), 1.0f);
      v = v <= 0.0031308f ? 12.92f * v : 1.055f * powf(v, 1.0f / 2.4f) - 0.055f;
      fputc((int)lroundf(v * 255.0f), f);
    }
  fclose(f);
}

int main(int argc, char **argv) {
  VkDebugUtilsMessengerEXT messenger;
  VkInstance instance = make_instance(&messenger);
  Gpu g = make_device(instance);
  const VkImageUsageFlags transfers = VK_IMAGE_USAGE_TRANSFER_SRC_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
  Image colour = make_image(&g, VK_FORMAT_R16G16B16A16_SFLOAT, W, H, transfers | VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT,
                            VK_IMAGE_ASPECT_COLOR_BIT);
  Image depth = make_image(&g, VK_FORMAT_D32_SFLOAT, W, H, transfers | VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
                           VK_IMAGE_ASPECT_DEPTH_BIT);
  Raster raster = make_raster(&g, &colour, &depth);
  Mapped vertices = make_mapped(&g, sizeof MESH, VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
  memcpy(vertices.data, MESH, sizeof MESH);
  const VkDeviceSize readback_bytes = (VkDeviceSize)W * H * 12; /* RGBA16F, then D32 */
  Mapped mesh_pixels = make_mapped(&g, readback_bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT);
  Mapped final_pixels = make_mapped(&g, readback_bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT);
  /* Further channels straight into the host's buffers: normals and coverage. */
  Mapped normals = make_mapped(&g, (VkDeviceSize)W * H * 12, VK_BUFFER_USAGE_TRANSFER_DST_BIT);
  Mapped coverage = make_mapped(&g, (VkDeviceSize)W * H * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT);
  VkSemaphoreCreateInfo sci = {.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
  VkSemaphore mesh_drawn, srug_done;
  VK(vkCreateSemaphore(g.device, &sci, NULL, &mesh_drawn));
  VK(vkCreateSemaphore(g.device, &sci, NULL, &srug_done));

  /* srug on the host's device. */
  PFN_vkGetInstanceProcAddr gipa = vkGetInstanceProcAddr;
  void *gipa_data = NULL;
  memcpy(&gipa_data, &gipa, sizeof gipa_data);
  srug_vulkan_device vulkan = {
      .instance = (void *)instance,
      .physical_device = (void *)g.physical,
      .device = (void *)g.device,
      .queue_family = g.family,
      .queue_index = 0,
      .get_instance_proc_addr = gipa_data,
      .enabled_features = SRUG_VULKAN_FEATURE_BUFFER_DEVICE_ADDRESS | SRUG_VULKAN_FEATURE_SHADER_INT64,
  };
  srug_context *ctx = NULL;
  srug_scene *scene = NULL;
  srug_renderer *r = NULL;
  CHECK(srug_context_create_from_vulkan(&vulkan, SRUG_CONTEXT_VALIDATION, &ctx));
  CHECK(srug_scene_create_demo(ctx, 20000, 7, &scene));
  CHECK(srug_renderer_create(ctx, W, H, 0, &r));
  const float sun[3] = {3.14159265f, 3.14159265f, 3.14159265f};
  CHECK(srug_renderer_set_sun(r, 260.0f, 50.0f, sun));
  CHECK(srug_renderer_set_shadow_map_reuse(r, true));
  const float black[3] = {0.0f, 0.0f, 0.0f};
  CHECK(srug_renderer_set_background(r, black));

  srug_vulkan_image colour_target = {.image = (uint64_t)(uintptr_t)colour.image,
                                     .format = VK_FORMAT_R16G16B16A16_SFLOAT,
                                     .width = W,
                                     .height = H,
                                     .usage = transfers | VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT,
                                     .layout_before = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                                     .layout_after = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL};
  srug_vulkan_image depth_target = {.image = (uint64_t)(uintptr_t)depth.image,
                                    .format = VK_FORMAT_D32_SFLOAT,
                                    .width = W,
                                    .height = H,
                                    .usage = transfers | VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
                                    .layout_before = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
                                    .layout_after = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL};
  srug_vulkan_semaphore wait = {(uint64_t)(uintptr_t)mesh_drawn, 0}, signal = {(uint64_t)(uintptr_t)srug_done, 0};
  srug_vulkan_buffer channel_targets[2] = {
      {(uint64_t)(uintptr_t)normals.buffer, (VkDeviceSize)W * H * 12, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
       SRUG_CHANNEL_NORMAL},
      {(uint64_t)(uintptr_t)coverage.buffer, (VkDeviceSize)W * H * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
       SRUG_CHANNEL_ALPHA}};
  srug_vulkan_targets targets = {.colour = &colour_target,
                                 .depth = &depth_target,
                                 .depth_convention = SRUG_DEPTH_VULKAN,
                                 .near = NEAR,
                                 .far = FAR,
                                 .composite = true,
                                 .buffers = channel_targets,
                                 .buffer_count = 2,
                                 .wait = &wait,
                                 .wait_count = 1,
                                 .signal = &signal,
                                 .signal_count = 1};

  /* Misuse is refused before any work. */
  printf("refusals:\n");
  float unused[3];
  EXPECT(srug_renderer_get_sun(r, NULL, unused), SRUG_ERROR_NULL_POINTER);
  EXPECT(srug_renderer_render_to_vulkan(r, scene, NULL), SRUG_ERROR_NULL_POINTER);
  srug_vulkan_image wrong = colour_target;
  wrong.format = VK_FORMAT_R8_UNORM;
  srug_vulkan_targets misstated = targets;
  misstated.colour = &wrong;
  EXPECT(srug_renderer_render_to_vulkan(r, scene, &misstated), SRUG_ERROR_INVALID_ARGUMENT);
  wrong = colour_target;
  wrong.width = W / 2;
  EXPECT(srug_renderer_render_to_vulkan(r, scene, &misstated), SRUG_ERROR_INVALID_ARGUMENT);
  wrong = colour_target;
  wrong.usage = VK_IMAGE_USAGE_TRANSFER_DST_BIT;
  EXPECT(srug_renderer_render_to_vulkan(r, scene, &misstated), SRUG_ERROR_INVALID_ARGUMENT);
  misstated = targets;
  srug_vulkan_buffer small = channel_targets[0];
  small.size = 16;
  misstated.buffers = &small;
  misstated.buffer_count = 1;
  EXPECT(srug_renderer_render_to_vulkan(r, scene, &misstated), SRUG_ERROR_INVALID_ARGUMENT);
  misstated = targets;
  misstated.wait_count = 1;
  misstated.wait = NULL;
  EXPECT(srug_renderer_render_to_vulkan(r, scene, &misstated), SRUG_ERROR_NULL_POINTER);

  float *reference = malloc((size_t)W * H * 16), *mesh_colour = malloc((size_t)W * H * 16);
  float *composite = malloc((size_t)W * H * 16), *mesh_depth = malloc((size_t)W * H * 4);
  float *channel = malloc((size_t)W * H * 12);
  REQUIRE(reference && mesh_colour && composite && mesh_depth && channel);
  double worst_psnr = INFINITY;
  long nearer = 0;
  for (int frame = 0; frame < FRAMES; frame++) {
    /* The camera walks down the street. */
    const float eye[3] = {-40.0f + 0.08f * (float)frame, -2.0f + 0.01f * (float)frame, 1.6f};
    const float target[3] = {eye[0] + 30.0f, -2.0f, 1.3f}, up[3] = {0.0f, 0.0f, 1.0f};
    float view[16], projection[16];
    Push push = {.eye = {eye[0], eye[1], eye[2], 1.0f}};
    look_at(view, eye, target, up);
    perspective(projection, 50.0f, (float)W / (float)H, NEAR, FAR);
    /* OpenGL clip space to Vulkan's: y down, depth in [0, 1]. */
    const float to_vulkan[16] = {1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 0.5f, 0, 0, 0, 0.5f, 1};
    mul(push.clip, projection, view);
    mul(push.clip, to_vulkan, push.clip);
    /* The same sun as the splats. */
    CHECK(srug_renderer_get_sun(r, push.sun_dir, push.sun_radiance));
    CHECK(srug_renderer_set_camera_matrices(r, view, projection));

    /* The host draws its mesh and keeps a copy of what it drew. */
    VkCommandBuffer cmd = begin(&g);
    VkClearValue clears[2] = {{.color = {{0.05f, 0.1f, 0.2f, 1.0f}}}, {.depthStencil = {1.0f, 0}}};
    VkRenderPassBeginInfo rbi = {.sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO,
                                 .renderPass = raster.pass,
                                 .framebuffer = raster.framebuffer,
                                 .renderArea = {{0, 0}, {W, H}},
                                 .clearValueCount = 2,
                                 .pClearValues = clears};
    vkCmdBeginRenderPass(cmd, &rbi, VK_SUBPASS_CONTENTS_INLINE);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, raster.pipeline);
    VkDeviceSize offset = 0;
    vkCmdBindVertexBuffers(cmd, 0, 1, &vertices.buffer, &offset);
    vkCmdPushConstants(cmd, raster.layout, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof push,
                       &push);
    vkCmdDraw(cmd, VERTICES, 1, 0, 0);
    vkCmdEndRenderPass(cmd);
    barrier(cmd, colour.image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
            VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_ACCESS_MEMORY_WRITE_BIT, VK_ACCESS_TRANSFER_READ_BIT);
    barrier(cmd, depth.image, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
            VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_ACCESS_MEMORY_WRITE_BIT, VK_ACCESS_TRANSFER_READ_BIT);
    copy_out(cmd, &colour, &depth, &mesh_pixels);
    barrier(cmd, colour.image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
            VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, 0, VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT);
    barrier(cmd, depth.image, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
            VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL, 0, VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT);
    submit(&g, cmd, VK_NULL_HANDLE, mesh_drawn);

    /* srug renders into the host's images, after the mesh, before the host reads them. */
    CHECK(srug_renderer_render_to_vulkan(r, scene, &targets));
    cmd = begin(&g);
    copy_out(cmd, &colour, &depth, &final_pixels);
    submit(&g, cmd, srug_done, VK_NULL_HANDLE);
    /* The channels in the host's buffers are the frame's, bit for bit. */
    CHECK(srug_renderer_read_channel(r, SRUG_CHANNEL_NORMAL, channel, (size_t)W * H * 3));
    REQUIRE(memcmp(channel, normals.data, (size_t)W * H * 12) == 0);
    CHECK(srug_renderer_read_channel(r, SRUG_CHANNEL_ALPHA, channel, (size_t)W * H));
    REQUIRE(memcmp(channel, coverage.data, (size_t)W * H * 4) == 0);

    /* The CPU reference: srug's splats behind the mesh's depth from host memory, over the mesh's colour. */
    const uint16_t *mesh_half = mesh_pixels.data, *final_half = final_pixels.data;
    memcpy(mesh_depth, (const char *)mesh_pixels.data + (size_t)W * H * 8, (size_t)W * H * 4);
    const float *final_depth = (const float *)((const char *)final_pixels.data + (size_t)W * H * 8);
    for (int i = 0; i < W * H * 4; i++) {
      mesh_colour[i] = half_to_float(mesh_half[i]);
      composite[i] = half_to_float(final_half[i]);
    }
    CHECK(srug_renderer_set_host_depth(r, mesh_depth, (size_t)W * H, SRUG_DEPTH_VULKAN, NEAR, FAR));
    CHECK(srug_renderer_render(r, scene));
    CHECK(srug_renderer_read_image(r, SRUG_FORMAT_RGBA32F_LINEAR, reference, (size_t)W * H * 16, 0));
    CHECK(srug_renderer_set_host_depth(r, NULL, 0, SRUG_DEPTH_VULKAN, NEAR, FAR));
    double peak = 0.0, squared = 0.0;
    for (int p = 0; p < W * H; p++) {
      float alpha = reference[4 * p + 3];
      for (int c = 0; c < 4; c++) {
        double expected = reference[4 * p + c] + (1.0 - alpha) * mesh_colour[4 * p + c];
        double diff = composite[4 * p + c] - expected;
        squared += diff * diff;
        peak = fmax(peak, fabs(expected));
      }
      REQUIRE(final_depth[p] <= mesh_depth[p]);
      if (final_depth[p] < mesh_depth[p]) nearer++;
    }
    double mse = squared / ((double)W * H * 4);
    double psnr = mse > 0.0 ? 10.0 * log10(peak * peak / mse) : INFINITY;
    if (psnr < worst_psnr) worst_psnr = psnr;
    if (psnr < 45.0) {
      fprintf(stderr, "frame %d: PSNR %.2f dB against the CPU reference\n", frame, psnr);
      exit(1);
    }
  }
  if (argc > 1) write_ppm(argv[1], composite);
  printf("composite: %d frames of %dx%d, worst PSNR %.1f dB against the CPU reference; "
         "%ld depth texels brought nearer by splats\n",
         FRAMES, W, H, worst_psnr, nearer);
  REQUIRE(nearer > 0);
  expect_no_validation_messages(ctx);
  pin_loaded_modules();
  CHECK(srug_renderer_destroy(r));
  CHECK(srug_scene_destroy(scene));
  CHECK(srug_context_destroy(ctx));

  /* The host tears down; srug left nothing on its device. */
  VK(vkDeviceWaitIdle(g.device));
  free(reference);
  free(mesh_colour);
  free(composite);
  free(mesh_depth);
  free(channel);
  free_mapped(&g, &normals);
  free_mapped(&g, &coverage);
  vkDestroySemaphore(g.device, mesh_drawn, NULL);
  vkDestroySemaphore(g.device, srug_done, NULL);
  free_mapped(&g, &vertices);
  free_mapped(&g, &mesh_pixels);
  free_mapped(&g, &final_pixels);
  vkDestroyPipeline(g.device, raster.pipeline, NULL);
  vkDestroyPipelineLayout(g.device, raster.layout, NULL);
  vkDestroyFramebuffer(g.device, raster.framebuffer, NULL);
  vkDestroyRenderPass(g.device, raster.pass, NULL);
  free_image(&g, &colour);
  free_image(&g, &depth);
  vkDestroyCommandPool(g.device, g.pool, NULL);
  vkDestroyDevice(g.device, NULL);
  printf("host messenger heard %d message(s)\n", heard);
  REQUIRE(heard == 0);
  destroy_instance(instance, messenger);
  return 0;
}
