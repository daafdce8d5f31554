/* Shared helpers of the C API tests. */
#ifndef SRUG_TEST_CHECK_H
#define SRUG_TEST_CHECK_H

#include <dlfcn.h>
#include <link.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "srug.h"

static void print_last_error(const char *what) {
  char msg[1024];
  size_t n = 0;
  srug_last_error(msg, sizeof msg, &n);
  fprintf(stderr, "%s: %s\n", what, msg);
}

/* Fails the program unless `call` returns SRUG_OK. */
#define CHECK(call)                                                                   \
  do {                                                                                \
    srug_status s_ = (call);                                                          \
    if (s_ != SRUG_OK) {                                                              \
      fprintf(stderr, "%s:%d: %s returned %s\n", __FILE__, __LINE__, #call,          \
              srug_status_name(s_));                                                  \
      print_last_error("  last error");                                               \
      exit(1);                                                                        \
    }                                                                                 \
  } while (0)

/* Fails the program unless `call` returns `expected` with a non-empty message. */
#define EXPECT(call, expected)                                                        \
  do {                                                                                \
    srug_status s_ = (call);                                                          \
    char m_[1024] = {0};                                                              \
    srug_last_error(m_, sizeof m_, NULL);                                             \
    if (s_ != (expected) || m_[0] == 0) {                                             \
      fprintf(stderr, "%s:%d: %s returned %s, expected %s (message \"%s\")\n",        \
              __FILE__, __LINE__, #call, srug_status_name(s_),                        \
              srug_status_name(expected), m_);                                        \
      exit(1);                                                                        \
    }                                                                                 \
    printf("  %-28s %s\n", srug_status_name(s_), m_);                                 \
  } while (0)

#define REQUIRE(cond)                                                                 \
  do {                                                                                \
    if (!(cond)) {                                                                    \
      fprintf(stderr, "%s:%d: requirement failed: %s\n", __FILE__, __LINE__, #cond); \
      exit(1);                                                                        \
    }                                                                                 \
  } while (0)

/* Keeps every loaded library (the Vulkan loader, driver and layers among them)
 * loaded after the last context is gone, so that LeakSanitizer can name them
 * (lsan.supp suppresses what the Vulkan stack keeps until exit); an unloaded
 * module's frames are anonymous and could not be matched. Call it once the
 * device has been used, before destroying the last context. */
static int pin_module(struct dl_phdr_info *info, size_t size, void *data) {
  (void)size;
  (void)data;
  if (info->dlpi_name != NULL && info->dlpi_name[0] != 0)
    (void)dlopen(info->dlpi_name, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
  return 0;
}

static void pin_loaded_modules(void) { dl_iterate_phdr(pin_module, NULL); }

/* Fails the program when the validation layer said anything. */
static void expect_no_validation_messages(srug_context *ctx) {
  size_t count = 0;
  char text[4096] = {0};
  CHECK(srug_context_take_validation_messages(ctx, &count, text, sizeof text));
  if (count != 0) {
    fprintf(stderr, "%zu validation message(s):\n%s\n", count, text);
    exit(1);
  }
}

#endif
