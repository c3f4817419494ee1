#include "util/file.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <regex>

#include "util/error.h"

namespace fs = std::filesystem;

namespace sl {

std::string temp_sibling(const std::string& path, bool keep_extension) {
  static std::atomic<uint64_t> counter{0};
  const fs::path p(path);
  const std::string name = p.filename().string();
  SL_CHECK(!name.empty(), "write ", path, ": the path names a folder, not a file");
  std::string tmp = "." + name + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter.fetch_add(1));
  if (keep_extension) tmp += p.extension().string();
  return (p.parent_path() / tmp).string();
}

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)) {
  const fs::path parent = fs::path(path_).parent_path();
  dir_ = parent.empty() ? "." : parent.string();
  tmp_ = temp_sibling(path_);
  fd_ = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  SL_CHECK(fd_ >= 0, "write ", path_, ": cannot create temporary file ", tmp_, ": ", std::strerror(errno));
}

AtomicFile::~AtomicFile() {
  if (fd_ >= 0) ::close(fd_);
  if (!committed_) ::unlink(tmp_.c_str());
}

void AtomicFile::write(const void* data, size_t n) {
  const char* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t w = ::write(fd_, p, n);
    if (w < 0 && errno == EINTR) continue;
    SL_CHECK(w > 0, "write ", path_, ": writing ", tmp_, " failed: ", std::strerror(errno));
    p += w;
    n -= static_cast<size_t>(w);
  }
}

void AtomicFile::commit() {
  SL_CHECK(::fsync(fd_) == 0, "write ", path_, ": fsync failed: ", std::strerror(errno));
  const int fd = fd_;
  fd_ = -1;
  SL_CHECK(::close(fd) == 0, "write ", path_, ": close failed: ", std::strerror(errno));
  SL_CHECK(::rename(tmp_.c_str(), path_.c_str()) == 0, "write ", path_, ": rename from ", tmp_, " failed: ",
           std::strerror(errno));
  committed_ = true;
  // Persist the rename itself; failure here loses durability, not consistency, so ignore it.
  const int dfd = ::open(dir_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

void write_file_atomic(const std::string& path, std::string_view bytes) {
  AtomicFile f(path);
  f.write(bytes.data(), bytes.size());
  f.commit();
}

AtomicDirectory::AtomicDirectory(std::string path) : path_(std::move(path)) {
  const fs::path parent = fs::absolute(path_).parent_path();
  std::error_code ec;
  fs::create_directories(parent, ec);
  SL_CHECK(!ec, "cannot create folder '", parent.string(), "': ", ec.message());
  tmp_ = temp_sibling(fs::absolute(path_).lexically_normal().string());
  fs::remove_all(tmp_, ec);
  fs::create_directories(tmp_, ec);
  SL_CHECK(!ec, "cannot create folder '", tmp_, "': ", ec.message());
}

AtomicDirectory::~AtomicDirectory() {
  std::error_code ec;
  if (!committed_) fs::remove_all(tmp_, ec);
}

std::string AtomicDirectory::file(const std::string& name) const { return (fs::path(tmp_) / name).string(); }

void AtomicDirectory::commit() {
  std::error_code ec;
  fs::remove_all(path_, ec);
  fs::rename(tmp_, path_, ec);
  SL_CHECK(!ec, "cannot rename '", tmp_, "' to '", path_, "': ", ec.message());
  committed_ = true;
}

int sweep_stale_temp_files(const std::string& dir) {
  static const std::regex kTemp(R"(^\..+\.tmp\.([0-9]+)(\.[0-9]+)?(\.[A-Za-z0-9]+)?$)");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return 0;
  int removed = 0;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    std::smatch m;
    if (!std::regex_match(name, m, kTemp)) continue;
    const long pid = std::stol(m[1].str());
    if (pid <= 0 || pid == ::getpid()) continue;
    if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;  // alive, or not ours to judge
    std::error_code rm;
    if (fs::remove_all(e.path(), rm) > 0 && !rm) ++removed;
  }
  return removed;
}

}  // namespace sl
