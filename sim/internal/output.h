// The simulator's way out: every stream's messages get their sequence number, pass through the stream's faults
// (stamp in the source clock, arrival after latency, drops, duplicates, reordering) and are written to the log in
// arrival order. Internal to sim/.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <queue>
#include <span>
#include <string>
#include <vector>

#include "core/log_writer.h"
#include "faults/faults.h"

namespace driftlab::sim {

class Output {
 public:
  using Listener = std::function<void(const std::string&, int64_t, std::span<const uint8_t>)>;
  Output(LogWriter& writer, const FaultConfig& faults, int64_t start_utime, Listener listener)
      : writer_(writer), faults_(faults), start_utime_(start_utime), listener_(std::move(listener)) {}

  /// The recorder's clock: the log time [us] of a message arriving at true (simulated) time t [us]. The identity
  /// unless the simulation runs slower than the wall clock the recorder keeps. Arrival callbacks get true times.
  void set_log_clock(std::function<int64_t(int64_t)> to_log) { to_log_ = std::move(to_log); }

  /// Registers a stream (once per channel) and returns its id.
  int add_stream(const std::string& channel);
  bool has_stream(const std::string& channel) const;
  /// Every stream's channel, in the order they were added.
  std::vector<std::string> channels() const;

  /// Publishes msg (any LCM type with a driftlab.header_t `header`) measured at true time `stamp_utime` and
  /// complete at true time `ready_utime` (a lidar's last beam) [us]. Sets header.seq and header.utime.
  template <typename T>
  void publish(int stream, T& msg, int64_t stamp_utime, int64_t ready_utime) {
    const int64_t seq = streams_[static_cast<std::size_t>(stream)].seq;
    if (!faults_for(stream, stamp_utime)) return;
    msg.header.seq = seq;
    msg.header.utime = stamp_utime;
    std::vector<uint8_t> bytes(static_cast<std::size_t>(msg.getEncodedSize()));
    msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    enqueue(stream, std::move(bytes), stamp_utime, ready_utime);
  }

  /// Publishes an encoded message made elsewhere (an on-board module's, header and all) measured at `stamp_utime`
  /// and complete at `ready_utime` [us]: the stream's faults apply as for publish(), a clock fault rewriting the
  /// header stamps; the publisher's own seq is kept. Arrivals never precede what was already written.
  void publish_encoded(int stream, std::span<const uint8_t> bytes, int64_t stamp_utime, int64_t ready_utime);

  /// Calls `fn` with every message of `channel` as it is written, at its arrival [us, true clock]: a subscriber
  /// inside the simulation (the arm's controller and commander), which sees what the log sees.
  using Arrival = std::function<void(int64_t, std::span<const uint8_t>)>;
  void on_arrival(const std::string& channel, Arrival fn) { arrivals_[channel] = std::move(fn); }

  /// Writes, in arrival order, every message that arrives before `before` [us, true clock]. An arrival callback
  /// may publish: what it publishes to arrive before `before` is written in the same call.
  Status flush(int64_t before);
  /// Writes a message directly at arrival time `utime` after flushing what arrives before it (the manifest).
  Status write_now(const std::string& channel, int64_t utime, const std::vector<uint8_t>& bytes);

  std::vector<driftlab::fault_t> manifest(int64_t end_utime) const;
  const std::map<std::string, int64_t>& written() const { return written_; }
  int64_t last_arrival() const { return last_arrival_; }

 private:
  struct Stream {
    std::string channel;
    int64_t seq = 0;
    std::optional<StreamFaultInjector> injector;
  };
  struct Pending {
    int64_t arrival;
    uint64_t order;
    int stream;
    std::shared_ptr<const std::vector<uint8_t>> bytes;
    bool operator>(const Pending& o) const { return arrival != o.arrival ? arrival > o.arrival : order > o.order; }
  };
  Status write(const std::string& channel, int64_t utime, std::span<const uint8_t> bytes);
  /// The stream's next seq through its faults, into deliveries_: false when the message is lost.
  bool faults_for(int stream, int64_t stamp_utime);
  /// Queues the deliveries_ of a message encoded with its true stamp: a clock fault moves every stamp it carries (a
  /// tf_t's transforms have their own), the transport delay counts from when it was complete (ready_utime), and no
  /// arrival precedes what was already written.
  void enqueue(int stream, std::vector<uint8_t> bytes, int64_t stamp_utime, int64_t ready_utime);

  LogWriter& writer_;
  const FaultConfig& faults_;
  int64_t start_utime_;
  Listener listener_;
  std::function<int64_t(int64_t)> to_log_;
  std::vector<Stream> streams_;
  std::vector<Delivery> deliveries_;
  std::priority_queue<Pending, std::vector<Pending>, std::greater<>> queue_;
  uint64_t order_ = 0;
  std::map<std::string, int64_t> written_;
  std::map<std::string, Arrival, std::less<>> arrivals_;
  int64_t last_arrival_ = 0;
};

}  // namespace driftlab::sim
