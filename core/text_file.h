// Reading a whole text file a user names (a config, a scenario, a URDF, a spec), refusing what would block or has
// no end. Thread-safety: reentrant.
#pragma once

#include <string>

#include "core/result.h"

namespace driftlab {

/// The whole file; `what` names it in errors ("PATH: the WHAT: ..."). What is not a regular file (a FIFO, a device,
/// a socket, a folder) is refused at once, without waiting on it, as is a file over 64 MiB.
Result<std::string> read_text_file(const std::string& path, const std::string& what);

}  // namespace driftlab
