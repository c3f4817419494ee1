// The sizes an OpenEXR header declares, read without OpenEXR.
//
// Why: OpenEXR allocates what a header declares while the file is being opened, before any
// caller can look at it. Found by tests/fuzz (issue 17), in the ASan fuzz build:
// - a 398-byte file whose dataWindow declared 3.6e9 pixels peaked at 300 MB and took 16 s,
//   OpenEXR sizing its decompression buffers by the window's width;
// - a 412-byte file whose string attribute declared 1.7 GB peaked at 2.1 GB and took 11 s.
// data/image_io calls this before OpenImageIO opens an EXR, and refuses both.
//
// Contract: summarize_exr_header(path) walks the header of an OpenEXR file attribute by
// attribute (name, type, size; values skipped), over every header of a multi-part file, and
// reports the largest width · height among the dataWindow attributes (int64, saturating at
// INT64_MAX: an int32 window can span 2^32 · 2^32), and the first attribute whose declared size
// runs past the end of the file. A file that is not OpenEXR (no magic number) gives an empty
// summary. Where the header cannot be walked further (truncated, malformed) the summary holds
// what was found before, and OpenEXR's own reader reports the damage as before. It costs a few
// reads whatever the file declares, and never throws.
#pragma once
#include <cstdint>
#include <string>

namespace sl::data {

struct ExrHeaderSummary {
  int64_t largest_window_pixels = 0;
  std::string attribute_past_end;  // empty when every attribute fits in the file
  int64_t attribute_bytes = 0;     // what that attribute declared
};

ExrHeaderSummary summarize_exr_header(const std::string& path);

}  // namespace sl::data
