// Every executable answers --help (exit 0) and meets a bad flag with one line "error: ..." and
// exit 2 (docs/DESIGN.md, "Executables").
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <string>

namespace sl::test {

namespace {

struct ProcessResult {
  int code;
  std::string out;
};

ProcessResult run(const std::string& cmd) {
  ProcessResult r{-1, ""};
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  while (fgets(buf.data(), buf.size(), p)) r.out += buf.data();
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::vector<std::string> executables() {
  std::vector<std::string> out;
  const std::filesystem::path dir = std::filesystem::path(STREETLIGHT_BINARY_DIR) / "tools";
  if (!std::filesystem::exists(dir)) return out;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (e.is_regular_file() && name.rfind("streetlight-", 0) == 0 &&
        (std::filesystem::status(e.path()).permissions() & std::filesystem::perms::owner_exec) != std::filesystem::perms::none)
      out.push_back(e.path().string());
  }
  return out;
}

TEST(Executables, EveryToolAnswersHelpAndRejectsBadFlagsWithExitCode2) {
  const auto exes = executables();
  if (exes.empty()) GTEST_SKIP() << "no executables built in " << STREETLIGHT_BINARY_DIR << "/tools";
  for (const std::string& exe : exes) {
    const ProcessResult help = run(exe + " --help");
    EXPECT_EQ(help.code, 0) << exe << "\n" << help.out;
    EXPECT_NE(help.out.find("usage"), std::string::npos) << exe;
    // The usage line names the program once ("usage: streetlight-x streetlight-x ..." was a bug).
    const std::string name = std::filesystem::path(exe).filename().string();
    EXPECT_EQ(help.out.find("usage: " + name + " " + name), std::string::npos) << exe << "\n" << help.out;
    EXPECT_EQ(help.out.find("(repeatable) (repeatable)"), std::string::npos) << exe << "\n" << help.out;
    const ProcessResult bad = run(exe + " --definitely-not-a-flag");
    EXPECT_EQ(bad.code, 2) << exe << "\n" << bad.out;
    EXPECT_EQ(bad.out.rfind("error: ", 0), 0u) << exe << " printed:\n" << bad.out;
    EXPECT_EQ(std::count(bad.out.begin(), bad.out.end(), '\n'), 1) << exe << " printed:\n" << bad.out;
  }
}

}  // namespace

}  // namespace sl::test
