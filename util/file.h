// Atomic outputs: a file or a folder is written under a temporary sibling name and renamed into
// place only when complete, so a crash or a kill never leaves a half-written output under its
// final name (docs/DESIGN.md, "Errors").
//
// Temporary names: "<dir>/.<name>.tmp.<pid>.<n>" (plus "<ext>" when keep_extension, so writers
// that choose a format by extension still work), unique within and across processes.
// sweep_stale_temp_files() removes such names whose process is gone — what a killed trainer or
// tool leaves behind — and never touches those of a live process.
// Throws: sl::Error naming the path and the system's reason when a create, write or rename fails.
#pragma once
#include <cstddef>
#include <string>
#include <string_view>

namespace sl {

// A unique temporary sibling of `path` (see above).
std::string temp_sibling(const std::string& path, bool keep_extension = false);

// Streams into a temporary sibling; commit() flushes, syncs and renames it over `path`. The
// destructor removes the temporary when commit() was never reached.
class AtomicFile {
 public:
  explicit AtomicFile(std::string path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  void write(const void* data, size_t n);
  void commit();
  const std::string& temp_path() const { return tmp_; }

 private:
  std::string path_, dir_, tmp_;
  int fd_ = -1;
  bool committed_ = false;
};

// The whole of `bytes` written to `path` through an AtomicFile.
void write_file_atomic(const std::string& path, std::string_view bytes);

// A temporary sibling folder of `path`; commit() renames it over `path` (replacing an existing
// folder there), the destructor removes it when commit() was never reached.
class AtomicDirectory {
 public:
  explicit AtomicDirectory(std::string path);
  ~AtomicDirectory();
  AtomicDirectory(const AtomicDirectory&) = delete;
  AtomicDirectory& operator=(const AtomicDirectory&) = delete;
  // The path of `name` inside the temporary folder.
  std::string file(const std::string& name) const;
  const std::string& temp_path() const { return tmp_; }
  void commit();

 private:
  std::string path_, tmp_;
  bool committed_ = false;
};

// Removes the temporary files and folders of `dir` (names as above) whose process no longer
// runs; returns how many were removed. A missing folder sweeps nothing.
int sweep_stale_temp_files(const std::string& dir);

}  // namespace sl
