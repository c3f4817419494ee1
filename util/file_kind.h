// A file's kind by its name: the extension test and the folder listing that the tools and the
// data sources share (image folders, intrinsics files, output formats).
//
// Contract:
// - has_extension(path, {".jpg", ".png"}): whether the path's last extension (std::filesystem's:
//   "a.tar.gz" → ".gz"; a leading-dot name such as ".png" has none) equals one of the given ones,
//   ignoring ASCII case. The given extensions are lower case with their dot.
// - files_with_extension(dir, exts): the regular files of `dir` (not recursive) with one of those
//   extensions, sorted by path, so every listing is the same on every machine. Throws sl::Error
//   naming the folder when it cannot be read.
#pragma once
#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

namespace sl {

bool has_extension(std::string_view path, std::initializer_list<std::string_view> extensions);

std::vector<std::string> files_with_extension(const std::string& dir, std::initializer_list<std::string_view> extensions);

}  // namespace sl
