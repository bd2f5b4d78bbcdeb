// Turning command-line inputs (files and folders) into the ordered list of frames a
// batch processes, and each frame's output path.
#pragma once

#include <string>
#include <vector>

namespace ssdo {

// Files are taken as given; a folder contributes its *.exr files (sorted by name),
// except outputs of ssdo (*.ssdo.exr). Returns false with a message naming the input
// when one does not exist.
bool expand_inputs(const std::vector<std::string>& inputs, std::vector<std::string>& frames,
                   std::string& error);

// OUT_DIR/STEM.ssdo.exr for INPUT = .../STEM.exr.
std::string output_path_for(const std::string& input, const std::string& output_dir);

// True when `output` exists and is at least as new as `input`.
bool output_up_to_date(const std::string& input, const std::string& output);

}  // namespace ssdo
