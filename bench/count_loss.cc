// Counts the messages of a benchmark channel missing from one or more logs, by the sequence number each payload
// starts with (see lcm_publisher.cc).
//   count_loss CHANNEL EXPECTED LOG...   ->  "received R lost L"
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "core/log_reader.h"

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: count_loss CHANNEL EXPECTED LOG...\n");
    return 2;
  }
  const std::string channel = argv[1];
  const uint64_t expected = std::strtoull(argv[2], nullptr, 10);
  std::vector<bool> seen(expected, false);
  uint64_t received = 0;
  for (int i = 3; i < argc; ++i) {
    auto reader = driftlab::LogReader::open(argv[i]);
    if (!reader) {
      std::fprintf(stderr, "count_loss: %s\n", reader.error().message.c_str());
      return 1;
    }
    driftlab::Event e;
    while (reader->next(e)) {
      if (e.channel != channel || e.data.size() < 8) continue;
      uint64_t seq;
      std::memcpy(&seq, e.data.data(), sizeof(seq));
      if (seq < expected && !seen[seq]) {
        seen[seq] = true;
        ++received;
      }
    }
  }
  std::printf("received %llu lost %llu\n", static_cast<unsigned long long>(received),
              static_cast<unsigned long long>(expected - received));
  return 0;
}
