// Turning command-line inputs (files and folders) into the ordered list of frames a
// batch processes, and each frame's output path.
#pragma once

#include <string>
#include <vector>

#include "service/file_version.h"

namespace ssdo {

// Files are taken as given; a folder contributes its *.exr files (sorted by name),
// except outputs of ssdo (*.ssdo.exr). Returns false with a message naming the input
// when one does not exist.
bool expand_inputs(const std::vector<std::string>& inputs, std::vector<std::string>& frames,
                   std::string& error);

// True for a name a frame can have: *.exr (any case), not an ssdo output (*.ssdo.exr),
// not hidden (".NAME", which is also how temp files are named).
bool is_frame_file(const std::string& path);

// Whether the file name `name` ends in .exr, in any case (NAME.exr, NAME.EXR).
bool has_exr_extension(const std::string& name);

// For a camera sidecar "DIR/NAME.camera.json" (formats/camera_io.h, sidecar_path_for):
// its frame "DIR/NAME.exr"; empty for any other name (hidden names included).
std::string frame_for_sidecar(const std::string& path);

// OUT_DIR/STEM.ssdo.exr for INPUT = .../STEM.exr.
std::string output_path_for(const std::string& input, const std::string& output_dir);

// `files` with each file once, in the order first given: one file however it is spelled
// ("x.exr", "$PWD/x.exr", "a/../x.exr"); links stay distinct files (their outputs are
// named after them).
std::vector<std::string> each_file_once(const std::vector<std::string>& files);

// OUT_DIR/STEM.error.json: where the service records why a frame failed.
std::string error_path_for(const std::string& input, const std::string& output_dir);

// Where the failure of a frame with an explicit output is recorded, beside it: OUT/X.error.json
// for OUT/X.ssdo.exr (the name error_path_for gives the frame X whose output that is), and
// OUT/NAME.exr.error.json for any other OUT/NAME.exr, which never names a watched frame's
// error file (theirs are named after outputs NAME.ssdo.exr).
std::string error_path_for_output(const std::string& output);

// True when `output` is a file (not a folder) at least as new as `input`'s last change: the later
// of its modification and status-change times, so a file renamed into place (whose
// mtime may be old) still counts as new.
bool output_up_to_date(const std::string& input, const std::string& output);

// output_up_to_date for the frame and for its camera sidecar when it has one: a sidecar
// that arrives or changes after the output makes the output stale too.
bool output_up_to_date_with_sidecar(const std::string& input, const std::string& output);

// output_up_to_date for each of `files` (the files the options name: --camera, --env).
bool output_up_to_date_with_all(const std::vector<std::string>& files, const std::string& output);

// A frame's file and its camera sidecar as found at one moment.
struct FrameFiles {
  FileVersion input, sidecar;
};
FrameFiles frame_files(const std::string& frame);

// Whether a frame's file or sidecar is no longer the version `found`.
bool changed_since(const std::string& frame, const FrameFiles& found);

// Dates `output` back to just before the last change of the frame's file and sidecar as `found`
// (after a worker that may have read an older version wrote it), so that the up-to-date
// test (output_up_to_date_with_sidecar) finds the changed files newer and a rerun or a
// restarted service computes the frame again. False when the time cannot be set.
bool mark_out_of_date(const std::string& output, const FrameFiles& found);

// Removes `output` and its previews (OUT/NAME.ssdo.<term>.png, formats/output_writer.h):
// a frame that failed leaves no picture of an earlier version of itself.
void remove_output_and_previews(const std::string& output);

// What an existing `output` says of how it was made, from one open of the file.
struct OutputMadeWith {
  // Its header says it was made by this version of ssdo with the options whose attribute is
  // `options_attribute` (request_options.h: kVersionAttribute, kOptionsAttribute,
  // options_attribute) and the neighbouring frames of `window_attribute`
  // (kWindowAttribute, sequence.h's window_attribute; empty: not compared): false for
  // another version (whose arithmetic may differ), other options or another window, and
  // for a file without them (unreadable, or not ssdo's).
  bool same_options = false;
  // Its header has ssdo's attributes: false for a damaged file or another program's.
  bool from_ssdo = false;
  // Every scanline chunk lies within the file (ExistingOutput::chunks_complete): false for
  // an output cut short.
  bool whole = false;
  // Each of its terms (channel name up to the first '.') has its preview beside it
  // (OUT/NAME.ssdo.<term>.png): what a run with --png needs of an output to skip it.
  bool previews = false;
};
OutputMadeWith output_made_with(const std::string& output, const std::string& options_attribute,
                                const std::string& window_attribute = {});

// Removes the temp files of this host's output writers that no longer run
// (".NAME.tmp-HOST-PID-*", and the older ".NAME.tmp-PID-err" / "-client", in `dir` and its
// subfolders, with HOST this host and no process PID: left by a kill -9); other hosts'
// files sharing the folder are left alone. A writer that still runs
// is waited for up to wait_s seconds: the worker of a batch or service killed just before
// this one started takes a moment to die (it is killed with its parent, and freeing a
// frame's memory takes ~0.1 s). Returns how many.
int remove_stale_temp_files(const std::string& dir, double wait_s = 2.0);

// Removes the temp files this host's process `pid` left in `dir` (not its subfolders): a
// worker that died or was killed while writing a frame's outputs. Returns how many.
int remove_temp_files_of(const std::string& dir, long pid);

}  // namespace ssdo
