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

/// Writes bytes to path+".partial", syncs it and renames it to path: a reader (another process, another node of a
/// shared file system) sees the old file or the whole new one. On failure removes the partial file, leaves path as
/// it was and returns an error (ErrorCode::kCannotWrite) naming path.
Status write_file_atomically(const std::string& path, std::string_view bytes);

}  // namespace driftlab
