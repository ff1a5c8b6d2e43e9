#include "core/mapped_file.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <utility>

namespace driftlab {
namespace {
// Release in steps this large, so madvise calls are rare.
constexpr uint64_t kReleaseStep = 16ull << 20;
// Map the pages ahead of the reader in steps this large: one madvise instead of a page fault every 64 KiB (each
// fault is an exception, costly under a hypervisor; a 700 MB log took 11,000 of them).
constexpr uint64_t kPopulateStep = 8ull << 20;
#ifndef MADV_POPULATE_READ
constexpr int MADV_POPULATE_READ = 22;  // Linux 5.14; older kernels refuse it, and the pages fault in as before
#endif
}  // namespace

Result<MappedFile> MappedFile::open(const std::string& path) {
  // O_NONBLOCK: a FIFO without a writer would block open() forever; with it, fstat below refuses the FIFO at once
  // (it has no effect on regular files).
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) return Error{path + ": cannot open: " + std::strerror(errno)};
  struct stat st {};
  if (fstat(fd, &st) != 0) {
    const int err = errno;
    ::close(fd);
    return Error{path + ": cannot stat: " + std::strerror(err)};
  }
  if (S_ISDIR(st.st_mode)) {
    ::close(fd);
    return Error{path + ": is a directory, not a log file"};
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    return Error{path + ": not a regular file (a FIFO, device or socket): give a log file"};
  }
  MappedFile file;
  file.size_ = static_cast<uint64_t>(st.st_size);
  if (file.size_ > 0) {
    void* p = mmap(nullptr, file.size_, PROT_READ, MAP_PRIVATE, fd, 0);
    if (p == MAP_FAILED) {
      const int err = errno;
      ::close(fd);
      return Error{path + ": cannot map " + std::to_string(file.size_) + " bytes: " + std::strerror(err)};
    }
    madvise(p, file.size_, MADV_SEQUENTIAL);
    file.data_ = static_cast<const uint8_t*>(p);
  }
  ::close(fd);
  return file;
}

MappedFile& MappedFile::operator=(MappedFile&& other) noexcept {
  if (this != &other) {
    if (data_ != nullptr) munmap(const_cast<uint8_t*>(data_), size_);
    data_ = std::exchange(other.data_, nullptr);
    size_ = std::exchange(other.size_, 0);
    released_ = std::exchange(other.released_, 0);
    last_offset_ = std::exchange(other.last_offset_, 0);
    ahead_until_ = std::exchange(other.ahead_until_, 0);
  }
  return *this;
}

MappedFile::~MappedFile() {
  if (data_ != nullptr) munmap(const_cast<uint8_t*>(data_), size_);
}

void MappedFile::release_before(uint64_t offset) {
  const uint64_t page = static_cast<uint64_t>(sysconf(_SC_PAGESIZE));
  if (data_ == nullptr) return;
  if (offset < released_) released_ = (offset / page) * page;  // after a seek backwards
  // A seek (backwards, or forwards past what was mapped ahead) maps ahead again from there.
  if (offset < last_offset_ || offset > ahead_until_) ahead_until_ = (offset / page) * page;
  last_offset_ = offset;
  if (ahead_until_ < size_ && offset + kPopulateStep > ahead_until_) {
    const uint64_t until = std::min(size_, ahead_until_ + 2 * kPopulateStep);
    madvise(const_cast<uint8_t*>(data_) + ahead_until_, until - ahead_until_, MADV_POPULATE_READ);
    ahead_until_ = until;
  }
  if (offset < released_ + 2 * kReleaseStep) return;
  const uint64_t until = ((offset - kReleaseStep) / page) * page;
  if (until <= released_) return;
  madvise(const_cast<uint8_t*>(data_) + released_, until - released_, MADV_DONTNEED);
  released_ = until;
}

}  // namespace driftlab
