#include "core/text_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>

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

Result<PartialFile> create_partial_of_its_own(const std::string& path) {
  static std::atomic<unsigned> counter{0};
  for (int attempt = 0; attempt < 1000; ++attempt) {
    PartialFile p;
    p.path = path + ".partial." + std::to_string(::getpid()) + "." + std::to_string(counter++);
    p.fd = ::open(p.path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
    if (p.fd >= 0) return p;
    if (errno != EEXIST) return Error{p.path + ": cannot create: " + std::strerror(errno), ErrorCode::kCannotWrite};
  }
  return Error{path + ".partial: cannot create a partial file of its own", ErrorCode::kCannotWrite};
}

Status write_file_atomically(const std::string& path, std::string_view bytes, AtomicWrite how) {
  std::string partial = path + ".partial";
  int fd = -1;
  if (how.partial_of_its_own) {
    auto own = create_partial_of_its_own(path);
    if (!own) return own.error();
    fd = own->fd;
    partial = own->path;
  } else {
    fd = ::open(partial.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  }
  if (fd < 0) return Error{path + ": cannot write: " + std::strerror(errno), ErrorCode::kCannotWrite};
  size_t done = 0;
  bool ok = true;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      ok = false;
      break;
    }
    done += static_cast<size_t>(n);
  }
  const int err = ok ? 0 : errno;
  if (ok && how.sync && ::fsync(fd) != 0) ok = false;
  if (::close(fd) != 0) ok = false;
  if (ok && std::rename(partial.c_str(), path.c_str()) != 0) ok = false;
  if (ok) return {};
  const int last = errno;
  std::remove(partial.c_str());
  return Error{path + ": cannot write: " + std::strerror(err != 0 ? err : last), ErrorCode::kCannotWrite};
}

}  // namespace driftlab
