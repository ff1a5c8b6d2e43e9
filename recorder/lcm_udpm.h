// LCM's UDP multicast transport, receive side: URLs, and the reassembly of datagrams into messages with
// per-sender accounting of sequence gaps (which stock LCM throws away).
//
// Wire format (all big-endian), as documented by LCM:
//   short message:  "LC02" magic | uint32 seqno | channel, NUL-terminated | data
//   fragment:       "LC03" magic | uint32 seqno | uint32 message size | uint32 fragment offset |
//                   uint16 fragment number | uint16 fragments in message | (fragment 0: channel, NUL) | data
// Every message a sender (one LCM instance, one source address) publishes takes the next seqno, whatever its
// channel; all fragments of a message share it. Thread-safety: a LcmReassembler belongs to one thread.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/result.h"

namespace driftlab::recorder {

/// udpm://GROUP:PORT?ttl=N&recv_buf_size=BYTES (LCM's URL syntax; defaults as LCM's).
struct UdpmUrl {
  std::string group = "239.255.76.67";
  uint16_t port = 7667;
  int ttl = 0;
  int64_t recv_buf_size = 0;  ///< 0: the recorder's default
};
Result<UdpmUrl> parse_udpm_url(const std::string& url);

/// Counters for one sender.
struct SenderCounters {
  int64_t messages = 0;
  int64_t bytes = 0;
  int64_t lost = 0;
  int64_t gaps = 0;
  int64_t out_of_order = 0;
  int64_t fragments_incomplete = 0;
  int64_t last_utime = 0;
};

/// A complete message; channel and data are valid until the next call to feed().
struct LcmMessage {
  std::string_view channel;
  std::span<const uint8_t> data;
  uint32_t seqno = 0;
  int64_t utime = 0;  ///< receive time of its first datagram [us]
};

class LcmReassembler {
 public:
  /// Largest message accepted; bigger sizes in a fragment header are treated as garbage.
  static constexpr uint32_t kMaxMessageBytes = 256u << 20;

  /// One datagram from sender (an opaque key, e.g. address and port) received at utime [us]. Returns the message
  /// it completes, if any. Datagrams that are not LCM packets are counted in garbage().
  std::optional<LcmMessage> feed(uint64_t sender, std::span<const uint8_t> datagram, int64_t utime);

  const std::map<uint64_t, SenderCounters>& senders() const { return counters_; }
  int64_t garbage() const { return garbage_; }

 private:
  /// The fragments of the message in progress, kept apart until all have come, so memory follows the bytes
  /// received rather than the size a (possibly bogus) header claims.
  struct Fragments {
    bool active = false;
    uint32_t seqno = 0;
    uint32_t size = 0;
    uint16_t count = 0;
    uint64_t bytes = 0;
    int64_t first_utime = 0;
    std::string channel;
    std::map<uint16_t, std::pair<uint32_t, std::vector<uint8_t>>> parts;  // number -> (offset, bytes)
  };
  struct SenderState {
    bool started = false;
    uint32_t next_seqno = 0;
    Fragments fragments;
  };

  /// Accounts for a new seqno from a sender: gaps, losses, late arrivals.
  void observe(SenderState& s, SenderCounters& c, uint32_t seqno);
  std::optional<LcmMessage> complete(SenderCounters& c, std::string_view channel, std::span<const uint8_t> data,
                                     uint32_t seqno, int64_t utime);

  std::map<uint64_t, SenderState> state_;
  std::vector<uint8_t> assembled_;  // the last fragmented message delivered
  std::map<uint64_t, SenderCounters> counters_;
  int64_t garbage_ = 0;
};

}  // namespace driftlab::recorder
