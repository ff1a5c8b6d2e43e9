// Helpers shared by the tests: scratch folders, files, deterministic payloads and whole-log reads.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "core/log_event.h"
#include "lcmtypes/validate.h"

namespace driftlab::test {

/// A fresh folder under the system's temporary folder, removed with its contents on destruction.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::string& path() const { return path_; }
  std::string file(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

std::vector<uint8_t> read_file(const std::string& path);
void write_file(const std::string& path, const std::vector<uint8_t>& bytes);

/// size bytes derived from seed; every 97th position holds an LCM sync word, to trip naive scanners.
std::vector<uint8_t> payload(uint64_t seed, size_t size);

/// An event copied out of a reader.
struct OwnedEvent {
  int64_t event_number;
  int64_t utime;
  std::string channel;
  std::vector<uint8_t> data;
  uint64_t offset;
  bool operator==(const OwnedEvent&) const = default;
};

/// The same events with offset set to 0, to compare with events written elsewhere.
std::vector<OwnedEvent> without_offsets(std::vector<OwnedEvent> events);

/// Every event of a log with LogReader, and the problems met.
std::vector<OwnedEvent> read_all(const std::string& path, std::vector<Problem>* problems = nullptr);
/// The messages of a log on the channels whose names start with `prefix`, in order, without the stamps: two runs
/// of a module that give the same wrote the same.
std::vector<std::pair<std::string, std::vector<uint8_t>>> messages_on(const std::string& path,
                                                                      const std::string& prefix);
std::vector<OwnedEvent> read_all_memory(const std::vector<uint8_t>& bytes, std::vector<Problem>* problems = nullptr);

/// The path of a file of the shared real data (DRIFTLAB_SHARED_DATA, ../shared/data beside the checkout), e.g.
/// shared_data("carmen/intel.orig.bag"). When it is missing the calling test is skipped, except under CI
/// (CI=true), where a missing shared file is a failure: CI always has ../shared beside the clone.
/// Use as: `auto bag = shared_data("..."); if (bag.empty()) return;`
std::string shared_data(const std::string& relative);

/// One run of the SLAM benchmark in the shared data (carmen/NAME.orig.bag, NAME-corrected.log.gz, NAME.relations;
/// NAME intel or aces), or all empty when one is missing (as shared_data: skipped, or failed under CI).
struct CarmenRun {
  std::string bag, corrected, relations;
  bool empty() const { return bag.empty() || corrected.empty() || relations.empty(); }
};
CarmenRun carmen_run(const std::string& name);

/// An LCM message encoded by its lcm-gen class.
template <typename T>
std::vector<uint8_t> encode(const T& m) {
  std::vector<uint8_t> b(static_cast<size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

/// An event's payload decoded by its lcm-gen class after the layout check every reader makes (lcmtypes::decode): a
/// payload that is not a well-formed message of T fails the test.
template <typename T>
T decode(const OwnedEvent& e) {
  T m;
  EXPECT_TRUE(lcmtypes::decode(e.data, m)) << e.channel;
  return m;
}

/// Overwrites 4 bytes at `at` with v, big-endian (as LCM encodes an int32_t): to forge hostile lengths.
inline void put_be32(std::vector<uint8_t>& b, size_t at, int32_t v) {
  const auto u = static_cast<uint32_t>(v);
  for (int i = 0; i < 4; ++i) b[at + static_cast<size_t>(i)] = static_cast<uint8_t>(u >> (24 - 8 * i));
}

/// Runs a shell command; returns its exit code and fills out with its standard output.
int run(const std::string& command, std::string* out = nullptr);

struct CmdResult {
  int code;
  std::string out;  ///< standard output
  std::string err;  ///< standard error
};
/// Runs a shell command and keeps both of its outputs.
CmdResult run_capture(const std::string& command);

}  // namespace driftlab::test
