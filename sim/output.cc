#include "sim/internal/output.h"

namespace driftlab::sim {

int Output::add_stream(const std::string& channel) {
  Stream s;
  s.channel = channel;
  if (auto it = faults_.streams.find(channel); it != faults_.streams.end()) {
    s.injector.emplace(channel, it->second, faults_.seed, start_utime_);
  }
  streams_.push_back(std::move(s));
  return static_cast<int>(streams_.size() - 1);
}

bool Output::has_stream(const std::string& channel) const {
  for (const Stream& s : streams_) {
    if (s.channel == channel) return true;
  }
  return false;
}

Status Output::write(const std::string& channel, int64_t utime, std::span<const uint8_t> bytes) {
  if (Status s = writer_.write(utime, channel, bytes); !s) return s;
  if (listener_) listener_(channel, utime, bytes);
  if (!arrivals_.empty()) {
    if (auto it = arrivals_.find(channel); it != arrivals_.end()) it->second(utime, bytes);
  }
  ++written_[channel];
  last_arrival_ = utime;
  return {};
}

Status Output::flush(int64_t before) {
  while (!queue_.empty() && queue_.top().arrival < before) {
    const Pending& p = queue_.top();
    if (Status s = write(streams_[static_cast<std::size_t>(p.stream)].channel, p.arrival, *p.bytes); !s) return s;
    queue_.pop();
  }
  return {};
}

Status Output::write_now(const std::string& channel, int64_t utime, const std::vector<uint8_t>& bytes) {
  if (Status s = flush(utime + 1); !s) return s;
  return write(channel, std::max(utime, last_arrival_), bytes);
}

std::vector<driftlab::fault_t> Output::manifest(int64_t end_utime) const {
  std::vector<driftlab::fault_t> out;
  for (const Stream& s : streams_) {
    if (!s.injector) continue;
    for (auto& f : s.injector->manifest(end_utime)) out.push_back(std::move(f));
  }
  return out;
}

}  // namespace driftlab::sim
