// A read-only memory mapping of a whole regular file: zero-copy access to logs and other inputs.
// Thread-safety: the bytes may be read from any thread; release_before() from one at a time.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "core/result.h"

namespace driftlab {

class MappedFile {
 public:
  /// Maps path; a directory, a missing or unreadable file gives an error naming the path.
  static Result<MappedFile> open(const std::string& path);

  MappedFile() = default;
  MappedFile(MappedFile&& other) noexcept { *this = std::move(other); }
  MappedFile& operator=(MappedFile&& other) noexcept;
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  ~MappedFile();

  std::span<const uint8_t> bytes() const { return {data_, size_}; }

  /// For a reader streaming forwards, at offset: drops the pages before offset from this process (they stay in
  /// the page cache, and the bytes stay readable: touching them again faults them back in), which keeps resident
  /// memory constant, and maps the next few MiB ahead of it at once.
  void release_before(uint64_t offset);

 private:
  const uint8_t* data_ = nullptr;
  uint64_t size_ = 0;
  uint64_t released_ = 0;
  uint64_t last_offset_ = 0;  ///< of the last call
  uint64_t ahead_until_ = 0;  ///< mapped ahead up to here
};

}  // namespace driftlab
