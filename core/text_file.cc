#include "core/text_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace driftlab {

Result<std::string> read_text_file(const std::string& path, const std::string& what) {
  constexpr off_t kMaxBytes = off_t{64} << 20;
  // O_NONBLOCK: opening a FIFO with no writer must not wait for one (the check below refuses it).
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return Error{path + ": cannot open the " + what + ": " + std::strerror(errno)};
  struct stat st {};
  std::string text;
  std::string problem;
  if (::fstat(fd, &st) != 0) {
    problem = std::string("cannot read it: ") + std::strerror(errno);
  } else if (!S_ISREG(st.st_mode)) {
    problem = "not a regular file (a FIFO, device, socket or folder)";
  } else if (st.st_size > kMaxBytes) {
    problem = "over 64 MiB: not a " + what;
  } else {
    text.resize(static_cast<std::size_t>(st.st_size));
    std::size_t done = 0;
    while (done < text.size()) {
      const ssize_t n = ::read(fd, text.data() + done, text.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      done += static_cast<std::size_t>(n);
    }
    if (done != text.size()) problem = "cannot read it whole";
  }
  ::close(fd);
  if (!problem.empty()) return Error{path + ": the " + what + ": " + problem};
  return text;
}

}  // namespace driftlab
