#include "core/install_layout.h"

#include <unistd.h>

#include <array>
#include <string>
#include <system_error>

namespace driftlab {
namespace {

namespace fs = std::filesystem;

// The layout below an install prefix, from the top CMakeLists.txt, which installs into the same folders.
constexpr std::string_view kDataDir = DRIFTLAB_INSTALL_DATADIR;
constexpr std::string_view kProgramDir = DRIFTLAB_INSTALL_PROGRAMDIR;

/// The prefixes the running program may sit in: PREFIX/bin/PROGRAM (and build/bin/PROGRAM) or
/// PREFIX/lib/driftlab/PROGRAM.
std::array<fs::path, 2> prefixes() {
  const fs::path dir = self_executable().parent_path();
  return {dir.parent_path(), dir.parent_path().parent_path()};
}

}  // namespace

fs::path self_executable() {
  std::error_code ec;
  fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path() : p;
}

fs::path data_dir() {
  const auto candidates = prefixes();
  for (const auto& prefix : candidates) {
    std::error_code ec;
    if (fs::is_directory(prefix / kDataDir, ec)) return prefix / kDataDir;
  }
  return candidates[0] / kDataDir;
}

fs::path data_path(std::string_view relative) { return data_dir() / relative; }

namespace {

/// `name` beside the running program, else in PREFIX/lib/driftlab; with `executable`, only an executable file.
fs::path sibling(std::string_view name, bool executable) {
  const fs::path self = self_executable();
  if (self.empty()) return {};
  for (const fs::path& p : {self.parent_path() / name, self.parent_path().parent_path() / kProgramDir / name}) {
    std::error_code ec;
    if (fs::is_regular_file(p, ec) && (!executable || ::access(p.c_str(), X_OK) == 0)) return p;
  }
  return {};
}

}  // namespace

fs::path sibling_program(std::string_view name) { return sibling(name, true); }

fs::path sibling_library(std::string_view name) { return sibling(name, false); }

}  // namespace driftlab
