#include "tools/common/released_models.h"

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>
#include <system_error>
#include <vector>

#include "util/error.h"

namespace sl::cli {
namespace fs = std::filesystem;

namespace {

// The file this code was loaded from: the Python extension when it runs inside python3, the
// executable otherwise (dladdr names the object that holds this function).
fs::path loaded_from() {
  Dl_info info{};
  std::error_code ec;
  if (dladdr(reinterpret_cast<void*>(&loaded_from), &info) != 0 && info.dli_fname && *info.dli_fname) {
    const fs::path p = fs::canonical(info.dli_fname, ec);
    if (!ec) return p;
  }
  const fs::path exe = fs::canonical("/proc/self/exe", ec);
  return ec ? fs::path() : exe;
}

// Every place looked at for `file` after the environment variable, in order.
std::vector<fs::path> candidates(const std::string& file) {
  std::vector<fs::path> out{fs::path("models") / file};
  if (const std::string dir = installed_models_dir(); !dir.empty()) out.push_back(fs::path(dir) / file);
  out.push_back(fs::path(STREETLIGHT_SOURCE_DIR) / "models" / file);
  return out;
}

std::string from_environment(const char* variable) {
  const char* env = std::getenv(variable);
  if (!env || !*env) return {};
  SL_CHECK(fs::is_regular_file(env), variable, " names '", env, "', which is not a file");
  return env;
}

}  // namespace

std::string installed_models_dir() {
  const fs::path from = loaded_from();
  if (from.empty()) return {};
  fs::path dir = from.parent_path();
  std::error_code ec;
  for (int up = 0; up < 3 && !dir.empty() && dir != dir.root_path(); ++up) {
    dir = dir.parent_path();
    const fs::path models = dir / STREETLIGHT_INSTALL_DATADIR / "streetlight" / "models";
    if (fs::is_directory(models, ec)) return models.string();
  }
  return {};
}

std::string released_model_path() {
  if (std::string env = from_environment("STREETLIGHT_MODEL"); !env.empty()) return env;
  std::string tried;
  for (const fs::path& p : candidates("streetlight.safetensors")) {
    if (fs::is_regular_file(p)) return p.string();
    tried += (tried.empty() ? "'" : ", '") + p.string() + "'";
  }
  SL_CHECK(false, "no --checkpoint given and the released model is missing (looked for ", tried,
           "); pass --checkpoint CKPT or set STREETLIGHT_MODEL");
  return {};
}

std::string released_sun_glare_path() {
  if (std::string env = from_environment("STREETLIGHT_SUN_GLARE"); !env.empty()) return env;
  for (const fs::path& p : candidates("sun_glare.safetensors"))
    if (fs::is_regular_file(p)) return p.string();
  return {};
}

}  // namespace sl::cli
