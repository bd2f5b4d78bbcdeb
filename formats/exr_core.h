// OpenEXRCore plumbing shared by the chunk paths of the reader (formats/gbuffer_reader) and
// the writer (formats/output_writer): a context that is always finished, and error messages
// kept for the error text instead of printed to stderr (OpenEXRCore's default handler).
#pragma once

#include <string>

#include <OpenEXR/openexr.h>

namespace ssdo::exr_core {

// An initializer whose error handler keeps the message on the calling thread.
exr_context_initializer_t quiet_initializer();

// The calling thread's kept message of the last failed call, else OpenEXRCore's text for
// `result`.
std::string error_text(exr_result_t result);

// Forgets the calling thread's kept message (before a call whose failure is reported).
void forget_error();

// Owns a context: exr_finish when it goes (a file being written is then abandoned; the
// caller removes it).
class Context {
 public:
  Context() = default;
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;
  ~Context() {
    if (context_) exr_finish(&context_);
  }
  exr_context_t get() const { return context_; }
  exr_context_t* out() { return &context_; }  // for exr_start_read / exr_start_write
  // Finishes now (a written file gets its chunk offset table); the context is gone after.
  exr_result_t finish() {
    exr_context_t c = context_;
    context_ = nullptr;
    return c ? exr_finish(&c) : EXR_ERR_SUCCESS;
  }

 private:
  exr_context_t context_ = nullptr;
};

}  // namespace ssdo::exr_core
