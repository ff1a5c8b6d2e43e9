#include "sim/internal/output.h"

#include <algorithm>

#include "lcmtypes/stream_header.h"

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

std::vector<std::string> Output::channels() const {
  std::vector<std::string> out;
  for (const Stream& s : streams_) out.push_back(s.channel);
  return out;
}

Status Output::write(const std::string& channel, int64_t utime, std::span<const uint8_t> bytes) {
  const int64_t log_time = to_log_ ? to_log_(utime) : utime;
  if (Status s = writer_.write(log_time, channel, bytes); !s) return s;
  if (listener_) listener_(channel, log_time, bytes);
  if (!arrivals_.empty()) {
    if (auto it = arrivals_.find(channel); it != arrivals_.end()) it->second(utime, bytes);
  }
  ++written_[channel];
  last_arrival_ = utime;
  return {};
}

Status Output::flush(int64_t before) {
  while (!queue_.empty() && queue_.top().arrival < before) {
    const Pending p = queue_.top();  // a copy: an arrival callback may push
    queue_.pop();
    if (Status s = write(streams_[static_cast<std::size_t>(p.stream)].channel, p.arrival, *p.bytes); !s) return s;
  }
  return {};
}

bool Output::faults_for(int stream, int64_t stamp_utime) {
  Stream& s = streams_[static_cast<std::size_t>(stream)];
  const int64_t seq = s.seq++;
  deliveries_.clear();
  if (s.injector) {
    s.injector->apply(seq, stamp_utime, deliveries_);
  } else {
    deliveries_.push_back({stamp_utime, stamp_utime});
  }
  return !deliveries_.empty();
}

void Output::enqueue(int stream, std::vector<uint8_t> bytes, int64_t stamp_utime, int64_t ready_utime) {
  auto data = std::make_shared<std::vector<uint8_t>>(std::move(bytes));
  if (const int64_t shift = deliveries_.front().stamp_utime - stamp_utime; shift != 0) {
    // The message's own stamp is true time: its header is recognised whatever its type.
    if (const auto stamp = lcmtypes::header_stamp(*data, stamp_utime)) {
      lcmtypes::map_stamps(*data, *stamp, [shift](int64_t t) { return t + shift; });
    }
  }
  for (const Delivery& d : deliveries_) {
    queue_.push({std::max(ready_utime + (d.arrival_utime - stamp_utime), last_arrival_), order_++, stream, data});
  }
}

void Output::publish_encoded(int stream, std::span<const uint8_t> bytes, int64_t stamp_utime, int64_t ready_utime) {
  if (!faults_for(stream, stamp_utime)) return;
  enqueue(stream, std::vector<uint8_t>(bytes.begin(), bytes.end()), stamp_utime, ready_utime);
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
