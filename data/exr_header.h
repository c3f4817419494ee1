// The declared size of an OpenEXR file, read from its header without OpenEXR.
//
// Why: OpenEXR sizes its line-offset table and line buffers from the header's dataWindow while
// a file is being opened, before any caller can look at the size: a 398-byte file declaring
// 3.6e9 pixels peaked at 300 MB and took 16 s in the ASan fuzz build (found by tests/fuzz).
// read_image and friends call this first, so such a file is refused before OpenEXR sees it.
//
// Contract: exr_declared_pixels(path) returns the largest width · height over the dataWindow
// attributes of every part of the file (one part, or each header of a multi-part file), as
// int64, saturating at INT64_MAX (an int32 window can span 2^32 · 2^32). It returns 0 when the
// file is not OpenEXR (no magic number) or declares no valid window; where the header cannot
// be walked further (truncated, malformed) it returns what it found before, and OpenEXR's own
// reader reports the damage as before. It reads the header attribute by attribute, skipping
// values, so it costs a few reads whatever the file declares. It never throws.
#pragma once
#include <cstdint>
#include <string>

namespace sl {

int64_t exr_declared_pixels(const std::string& path);

}  // namespace sl
