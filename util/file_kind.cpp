#include "util/file_kind.h"

#include <algorithm>
#include <filesystem>
#include <system_error>

#include "util/error.h"

namespace sl {

bool has_extension(std::string_view path, std::initializer_list<std::string_view> extensions) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext)
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  return std::any_of(extensions.begin(), extensions.end(), [&](std::string_view e) { return ext == e; });
}

std::vector<std::string> files_with_extension(const std::string& dir, std::initializer_list<std::string_view> extensions) {
  std::vector<std::string> out;
  std::error_code ec;
  for (std::filesystem::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code file_ec;
    if (it->is_regular_file(file_ec) && has_extension(it->path().string(), extensions)) out.push_back(it->path().string());
  }
  SL_CHECK(!ec, "folder '", dir, "' cannot be read: ", ec.message());
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace sl
