#include "data/exr_header.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <fstream>

namespace sl::data {

namespace {

// OpenEXR file layout 2.0: magic 20000630, a version word whose bit 12 marks a multi-part file,
// then headers of attributes (name\0 type\0 int32 size, value), each header ending in an empty
// name; a multi-part file ends its list of headers with an empty header.
constexpr unsigned char kMagic[4] = {0x76, 0x2f, 0x31, 0x01};
constexpr uint32_t kMultiPartFlag = 0x1000;
constexpr size_t kMaxNameLength = 255;  // long-name files; short names are at most 31

uint32_t little_endian_u32(const unsigned char* p) {
  return uint32_t{p[0]} | uint32_t{p[1]} << 8 | uint32_t{p[2]} << 16 | uint32_t{p[3]} << 24;
}

int32_t little_endian_i32(const unsigned char* p) {
  const uint32_t u = little_endian_u32(p);
  int32_t v;
  std::memcpy(&v, &u, sizeof v);
  return v;
}

bool read_name(std::istream& in, std::string& out) {
  out.clear();
  char c;
  while (in.get(c)) {
    if (c == '\0') return true;
    if (out.size() == kMaxNameLength) return false;
    out.push_back(c);
  }
  return false;
}

}  // namespace

ExrHeaderSummary summarize_exr_header(const std::string& path) {
  ExrHeaderSummary r;
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  const std::streamoff file_bytes = in.tellg();
  unsigned char head[8];
  if (!in.seekg(0) || !in.read(reinterpret_cast<char*>(head), sizeof head) || std::memcmp(head, kMagic, 4) != 0)
    return r;
  const bool multi_part = (little_endian_u32(head + 4) & kMultiPartFlag) != 0;
  std::string name, type;
  while (true) {
    bool empty_header = true;
    while (true) {
      if (!read_name(in, name)) return r;
      if (name.empty()) break;
      empty_header = false;
      unsigned char size_bytes[4];
      if (!read_name(in, type) || !in.read(reinterpret_cast<char*>(size_bytes), 4)) return r;
      const int32_t size = little_endian_i32(size_bytes);
      if (size < 0) return r;
      if (size > file_bytes - in.tellg()) {
        r.attribute_past_end = name;
        r.attribute_bytes = size;
        return r;
      }
      if (name == "dataWindow" && type == "box2i" && size == 16) {
        unsigned char box[16];
        if (!in.read(reinterpret_cast<char*>(box), sizeof box)) return r;
        const int64_t width = int64_t{little_endian_i32(box + 8)} - little_endian_i32(box) + 1;
        const int64_t height = int64_t{little_endian_i32(box + 12)} - little_endian_i32(box + 4) + 1;
        if (width > 0 && height > 0)  // each at most 2^32: saturate, since 2^32 · 2^32 is past int64
          r.largest_window_pixels =
              std::max(r.largest_window_pixels, width > INT64_MAX / height ? INT64_MAX : width * height);
      } else if (!in.seekg(size, std::ios::cur)) {
        return r;
      }
    }
    if (!multi_part || empty_header) return r;
  }
}

}  // namespace sl::data
