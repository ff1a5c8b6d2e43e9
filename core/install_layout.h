// Where driftlab's programs find their data (scenarios, worlds, robots) and each other at run time: relative to the
// running program, never through a path compiled in, so an installed driftlab works with the source tree gone.
//
// One layout serves the install tree and the build tree (docs/install.md):
//   PREFIX/bin/driftlab                the front end; build/bin/driftlab in the build tree
//   PREFIX/lib/driftlab/driftlab-*     the programs it runs (apps/commands.h), and the libraries they load only
//                                      when asked (driftlab-icp-slam.so); beside it in the build tree
//   PREFIX/share/driftlab/             scenarios/, worlds/, robots/; in the build tree build/share/driftlab/ holds
//                                      symlinks to sim/'s folders, made when CMake configures
#pragma once

#include <filesystem>
#include <string_view>

namespace driftlab {

/// The running program (/proc/self/exe); empty when it cannot be read.
std::filesystem::path self_executable();

/// The data folder: share/driftlab beside the running program's bin/ (or lib/driftlab/) folder. When neither
/// layout holds it, the first candidate (PROGRAM_DIR/../share/driftlab), so that an error names where it looked.
std::filesystem::path data_dir();

/// A file or folder in the data folder, e.g. data_path("scenarios/indoor.yaml").
std::filesystem::path data_path(std::string_view relative);

/// The driftlab program `name` (driftlab-sim, ...): beside the running program (the build tree, or a program
/// itself in lib/driftlab), else in PREFIX/lib/driftlab when the running one is PREFIX/bin/driftlab. Empty when
/// neither is an executable file (the caller may then look in PATH).
std::filesystem::path sibling_program(std::string_view name);

/// A library loaded at run time (driftlab-icp-slam.so) where sibling_program finds programs; it need not be
/// executable (Debian's CMake installs shared objects without the bit). Empty when neither is a file.
std::filesystem::path sibling_library(std::string_view name);

}  // namespace driftlab
