#include "recorder/lcm_udpm.h"

#include <arpa/inet.h>

#include <charconv>
#include <cstring>

#include "core/log_format.h"

namespace driftlab::recorder {
namespace {
constexpr uint32_t kMagicShort = 0x4c433032;  // "LC02"
constexpr uint32_t kMagicLong = 0x4c433033;   // "LC03"
constexpr size_t kShortHeader = 8;
constexpr size_t kLongHeader = 20;
constexpr size_t kMaxChannel = 255;

uint16_t load_be16(const uint8_t* p) { return static_cast<uint16_t>((p[0] << 8) | p[1]); }

/// The NUL-terminated channel at the start of bytes, or nullopt when there is none.
std::optional<std::string_view> channel_at(std::span<const uint8_t> bytes) {
  const size_t limit = std::min(bytes.size(), kMaxChannel + 1);
  const void* nul = std::memchr(bytes.data(), 0, limit);
  if (nul == nullptr || nul == bytes.data()) return std::nullopt;
  return std::string_view(reinterpret_cast<const char*>(bytes.data()),
                          static_cast<size_t>(static_cast<const uint8_t*>(nul) - bytes.data()));
}

template <typename T>
bool parse_number(std::string_view text, T& out) {
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
  return ec == std::errc() && end == text.data() + text.size();
}
}  // namespace

Result<UdpmUrl> parse_udpm_url(const std::string& url) {
  const std::string scheme = "udpm://";
  if (url.rfind(scheme, 0) != 0) return Error{"LCM URL '" + url + "': only udpm:// is supported"};
  UdpmUrl u;
  std::string_view rest(url);
  rest.remove_prefix(scheme.size());
  std::string_view query;
  if (const size_t q = rest.find('?'); q != std::string_view::npos) {
    query = rest.substr(q + 1);
    rest = rest.substr(0, q);
  }
  if (!rest.empty()) {
    const size_t colon = rest.rfind(':');
    const std::string_view host = colon == std::string_view::npos ? rest : rest.substr(0, colon);
    if (!host.empty()) u.group = std::string(host);
    if (colon != std::string_view::npos && !parse_number(rest.substr(colon + 1), u.port)) {
      return Error{"LCM URL '" + url + "': bad port '" + std::string(rest.substr(colon + 1)) + "'"};
    }
  }
  in_addr addr{};
  if (inet_pton(AF_INET, u.group.c_str(), &addr) != 1 || (ntohl(addr.s_addr) >> 28) != 0xE) {
    return Error{"LCM URL '" + url + "': '" + u.group + "' is not an IPv4 multicast address"};
  }
  while (!query.empty()) {
    const size_t amp = query.find('&');
    const std::string_view item = query.substr(0, amp);
    query = amp == std::string_view::npos ? std::string_view() : query.substr(amp + 1);
    const size_t eq = item.find('=');
    const std::string_view key = item.substr(0, eq);
    const std::string_view value = eq == std::string_view::npos ? std::string_view() : item.substr(eq + 1);
    bool ok = true;
    if (key == "ttl") {
      ok = parse_number(value, u.ttl);
    } else if (key == "recv_buf_size") {
      ok = parse_number(value, u.recv_buf_size);
    } else {
      return Error{"LCM URL '" + url + "': unknown option '" + std::string(key) + "'"};
    }
    if (!ok) return Error{"LCM URL '" + url + "': bad value for " + std::string(key)};
  }
  return u;
}

void LcmReassembler::observe(SenderState& s, SenderCounters& c, uint32_t seqno) {
  if (!s.started) {
    s.started = true;
    s.next_seqno = seqno + 1;
    return;
  }
  const uint32_t ahead = seqno - s.next_seqno;  // modulo 2^32: wraps around
  if (ahead == 0) {
    s.next_seqno = seqno + 1;
  } else if (ahead < 0x80000000u) {
    c.lost += ahead;
    ++c.gaps;
    s.next_seqno = seqno + 1;
  } else {
    ++c.out_of_order;  // older than expected: late, or a duplicate
  }
}

std::optional<LcmMessage> LcmReassembler::complete(SenderCounters& c, std::string_view channel,
                                                   std::span<const uint8_t> data, uint32_t seqno, int64_t utime) {
  ++c.messages;
  c.bytes += static_cast<int64_t>(data.size());
  c.last_utime = utime;
  return LcmMessage{channel, data, seqno, utime};
}

std::optional<LcmMessage> LcmReassembler::feed(uint64_t sender, std::span<const uint8_t> d, int64_t utime) {
  const uint32_t magic = d.size() >= 4 ? logfmt::load_be32(d.data()) : 0;
  if (magic == kMagicShort && d.size() > kShortHeader) {
    const auto channel = channel_at(d.subspan(kShortHeader));
    if (!channel) {
      ++garbage_;
      return std::nullopt;
    }
    const uint32_t seqno = logfmt::load_be32(d.data() + 4);
    SenderState& s = state_[sender];
    SenderCounters& c = counters_[sender];
    if (s.fragments.active && s.fragments.seqno != seqno) {
      // A sender sends all fragments of a message before its next message: the one in progress is lost.
      ++c.fragments_incomplete;
      s.fragments.active = false;
    }
    observe(s, c, seqno);
    return complete(c, *channel, d.subspan(kShortHeader + channel->size() + 1), seqno, utime);
  }
  if (magic != kMagicLong || d.size() < kLongHeader) {
    ++garbage_;
    return std::nullopt;
  }
  const uint32_t seqno = logfmt::load_be32(d.data() + 4);
  const uint32_t size = logfmt::load_be32(d.data() + 8);
  const uint32_t offset = logfmt::load_be32(d.data() + 12);
  const uint16_t number = load_be16(d.data() + 16);
  const uint16_t count = load_be16(d.data() + 18);
  std::span<const uint8_t> payload = d.subspan(kLongHeader);
  std::optional<std::string_view> channel;
  if (number == 0) {
    channel = channel_at(payload);
    if (!channel) {
      ++garbage_;
      return std::nullopt;
    }
    payload = payload.subspan(channel->size() + 1);
  }
  if (size > kMaxMessageBytes || count == 0 || number >= count || offset > size || payload.size() > size - offset) {
    ++garbage_;
    return std::nullopt;
  }
  SenderState& s = state_[sender];
  SenderCounters& c = counters_[sender];
  Fragments& f = s.fragments;
  if (!f.active || f.seqno != seqno || f.size != size || f.count != count) {
    if (f.active) ++c.fragments_incomplete;  // a new message began before the last one completed
    if (f.active && f.seqno == seqno) {
      // The same seqno with another shape: not a fragment of the message in progress.
      ++garbage_;
      f.active = false;
      return std::nullopt;
    }
    observe(s, c, seqno);
    f.active = true;
    f.seqno = seqno;
    f.size = size;
    f.count = count;
    f.bytes = 0;
    f.first_utime = utime;
    f.channel.clear();
    f.parts.clear();
  }
  if (f.parts.count(number) != 0) return std::nullopt;  // a duplicate fragment
  if (channel) f.channel.assign(*channel);
  f.parts.emplace(number, std::make_pair(offset, std::vector<uint8_t>(payload.begin(), payload.end())));
  f.bytes += payload.size();
  if (f.parts.size() < count) return std::nullopt;
  f.active = false;
  if (f.bytes != size) {  // the fragments do not tile the message
    ++garbage_;
    ++c.fragments_incomplete;
    return std::nullopt;
  }
  assembled_.assign(size, 0);
  for (const auto& [number, part] : f.parts) {
    if (!part.second.empty()) std::memcpy(assembled_.data() + part.first, part.second.data(), part.second.size());
  }
  f.parts.clear();
  return complete(c, f.channel, assembled_, seqno, f.first_utime);
}

}  // namespace driftlab::recorder
