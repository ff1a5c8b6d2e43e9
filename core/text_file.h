// Reading a whole text file a user names (a config, a scenario, a URDF, a spec), refusing what would block or has
// no end; writing one whole or not at all. Thread-safety: reentrant.
#pragma once

#include <string>
#include <string_view>

#include "core/result.h"

namespace driftlab {

/// The whole file; `what` names it in errors ("PATH: the WHAT: ..."). What is not a regular file (a FIFO, a device,
/// a socket, a folder) is refused at once, without waiting on it, as is a file over 64 MiB.
Result<std::string> read_text_file(const std::string& path, const std::string& what);

/// How write_file_atomically writes.
struct AtomicWrite {
  /// Syncs the file before the rename, so that after a crash, or on another node of a shared file system, the new
  /// name never shows a file still empty (batch's markers and results). A command's own outputs do without.
  bool sync = false;
  /// Writes through a partial file of this process's own (PATH.partial.PID.N, created exclusively), for a path that
  /// processes may write at once (a cache): each renames a whole file into place.
  bool partial_of_its_own = false;
};
inline constexpr AtomicWrite kSynced{.sync = true};

/// A partial file of this process's own beside path, created exclusively (PATH.partial.PID.N, never following a
/// link): processes writing one path at once (a cache) each write their own and rename it whole into place.
struct PartialFile {
  int fd = -1;
  std::string path;
};
Result<PartialFile> create_partial_of_its_own(const std::string& path);

/// Writes bytes to a partial file beside path (path+".partial") and renames it to path: a reader sees the old file
/// or the whole new one. On failure removes the partial file, leaves path as it was and returns an error
/// (ErrorCode::kCannotWrite) naming path.
Status write_file_atomically(const std::string& path, std::string_view bytes, AtomicWrite how = {});

}  // namespace driftlab
