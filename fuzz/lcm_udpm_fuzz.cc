// libFuzzer target: any sequence of datagrams (the input split at 0xFF 0xFE markers, each from one of four
// senders) fed to the recorder's LCM reassembler must neither crash nor yield a message outside the datagram
// or the reassembly buffer, and counters must stay consistent.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <span>

#include "recorder/lcm_udpm.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  driftlab::recorder::LcmReassembler r;
  size_t start = 0;
  int64_t messages = 0;
  for (size_t i = 0; i <= size; ++i) {
    const bool end = i == size || (i + 1 < size && data[i] == 0xFF && data[i + 1] == 0xFE);
    if (!end) continue;
    const std::span<const uint8_t> datagram(data + start, i - start);
    const uint64_t sender = datagram.empty() ? 0 : datagram[0] & 3;
    if (auto m = r.feed(sender, datagram, static_cast<int64_t>(i))) {
      ++messages;
      if (m->channel.empty() || m->channel.size() > 255) std::abort();
      if (std::memchr(m->channel.data(), 0, m->channel.size()) != nullptr) std::abort();
      if (m->data.size() > driftlab::recorder::LcmReassembler::kMaxMessageBytes) std::abort();
    }
    start = i + 2;
    ++i;
  }
  int64_t counted = 0;
  for (const auto& [sender, c] : r.senders()) {
    if (c.lost < 0 || c.gaps < 0 || c.gaps > c.lost) std::abort();
    counted += c.messages;
  }
  if (counted != messages) std::abort();
  return 0;
}
