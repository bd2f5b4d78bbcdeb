// What the batch and the service take from a worker's response (service/worker_process.h,
// read_worker_response): whether a failure is worth trying again comes from the worker's
// "out_of_memory", never from the words of the message; what is logged has no control
// characters.
#include "service/worker_process.h"

#include <gtest/gtest.h>

namespace ssdo {
namespace {

WorkerResult read(const nlohmann::json& j) {
  WorkerResult r;
  read_worker_response(j, r);
  return r;
}

TEST(WorkerResponse, OnlyTheOutOfMemoryFieldMakesAFailureTransient) {
  // A damaged frame whose name says "out of memory" failed for good.
  const WorkerResult damaged =
      read({{"ok", false}, {"error", "/f/out of memory.exr: cannot read pixels (damaged or truncated file): x"}});
  EXPECT_FALSE(damaged.ok());
  EXPECT_FALSE(damaged.transient);
  const WorkerResult memory = read({{"ok", false},
                                    {"error", "/f/a.exr: std::bad_alloc (out of memory: the frame needs more than "
                                              "the worker's limit of 300 MiB, see --memory-limit)"},
                                    {"out_of_memory", true}});
  EXPECT_FALSE(memory.ok());
  EXPECT_TRUE(memory.transient);
  // A field of another type counts as absent.
  EXPECT_FALSE(read({{"ok", false}, {"error", "e"}, {"out_of_memory", "yes"}}).transient);
}

TEST(WorkerResponse, AFailureWithoutAMessageStillFails) {
  EXPECT_EQ(read({{"ok", false}}).error, "the worker reported a failure");
  EXPECT_EQ(read({{"ok", false}, {"error", 3}}).error, "the worker reported a failure");
  EXPECT_TRUE(read({{"ok", true}}).ok());
}

TEST(WorkerResponse, FieldsAreReadAndControlCharactersEscaped) {
  const WorkerResult r = read({{"ok", true},
                               {"read_ms", 12.5},
                               {"compute_ms", 30},
                               {"write_ms", "fast"},
                               {"width", 640},
                               {"height", 360},
                               {"page_faults", 1234},
                               {"terms", {"ao", 7, "composite"}},
                               {"notes", {"view a\nb.exr not used", "tab\there"}},
                               {"window", {{"views", 1}, {"temporal", 1}, {"note", "computed with\rfewer"}}}});
  EXPECT_TRUE(r.ok());
  EXPECT_DOUBLE_EQ(r.times.read_ms, 12.5);
  EXPECT_DOUBLE_EQ(r.times.compute_ms, 30.0);
  EXPECT_DOUBLE_EQ(r.times.write_ms, 0.0);
  EXPECT_EQ(r.width_px, 640);
  EXPECT_EQ(r.height_px, 360);
  EXPECT_EQ(r.page_faults, 1234);
  EXPECT_EQ(r.terms, (std::vector<std::string>{"ao", "composite"}));
  EXPECT_EQ(r.notes, (std::vector<std::string>{"view a\\nb.exr not used", "tab\\there"}));
  EXPECT_EQ(r.views_per_side, 1);
  EXPECT_EQ(r.temporal_per_side, 1);
  EXPECT_EQ(r.window_note, "computed with\\rfewer");
  EXPECT_TRUE(r.window_reduced());
  // Sizes and counts are integers in range, else absent.
  const WorkerResult odd =
      read({{"ok", true}, {"width", 1e300}, {"height", -5}, {"page_faults", "many"}, {"window", {{"views", 2.5}}}});
  EXPECT_EQ(odd.width_px, 0);
  EXPECT_EQ(odd.page_faults, 0);
  EXPECT_EQ(odd.height_px, 0);
  EXPECT_EQ(odd.views_per_side, 0);
}

}  // namespace
}  // namespace ssdo
