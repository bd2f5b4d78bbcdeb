#include "formats/exr_core.h"

namespace ssdo::exr_core {
namespace {

thread_local std::string kept_message;

void keep_message(exr_const_context_t, exr_result_t, const char* message) {
  kept_message = message ? message : "";
}

}  // namespace

exr_context_initializer_t quiet_initializer() {
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  init.error_handler_fn = keep_message;
  return init;
}

std::string error_text(exr_result_t result) {
  return kept_message.empty() ? std::string(exr_get_default_error_message(result)) : kept_message;
}

void forget_error() { kept_message.clear(); }

}  // namespace ssdo::exr_core
