// The Bus: how modules (SLAM, estimator, controller) receive messages and publish results, unaware of whether the
// messages come live from LCM or from a log on a virtual clock. A module subscribes in start(), handles messages in
// its handlers and publishes through the same bus; its notion of "now" is the bus's (on replay: the arrival time of
// the message being handled), never the wall clock.
// Thread-safety: a Bus calls a module's handlers from one thread at a time; modules need no locking of their own.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/result.h"
#include "core/time.h"

namespace driftlab {

/// A message on the bus: its channel, when it arrived (the bus's clock), and its encoded bytes (valid during the
/// handler only).
struct BusMessage {
  std::string_view channel;
  Time time;
  std::span<const uint8_t> data;
};

using BusHandler = std::function<void(const BusMessage&)>;

class Bus {
 public:
  virtual ~Bus() = default;
  /// Calls `handler` for every message on a channel fully matching `channel_regex` (ECMAScript), as LCM does.
  virtual void subscribe(const std::string& channel_regex, BusHandler handler) = 0;
  /// Publishes encoded bytes on a channel, at the bus's current time.
  virtual void publish(std::string_view channel, std::span<const uint8_t> data) = 0;
  /// The bus's current time: the arrival time of the message being handled (on replay the log's, live the
  /// receiver's wall clock); inside a timer, the tick's.
  virtual Time now() const = 0;
  /// Calls `fn` every `period` (positive) of bus time, at whole multiples of it (like a ROS timer on sim time). On
  /// replay a tick fires, with now() at the tick, before the first message at or after it; none after the last.
  virtual void every(Duration period, std::function<void()> fn) = 0;
  /// Where a module may write files it produces (maps): a path prefix such as "out/session.replay"; the module
  /// appends its own suffix ("-map.png"). Empty: write no files.
  virtual std::string artifact_prefix() const { return {}; }

  /// Encodes and publishes an LCM message.
  template <typename T>
  void publish_message(std::string_view channel, const T& msg) {
    std::vector<uint8_t> bytes(static_cast<size_t>(msg.getEncodedSize()));
    msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    publish(channel, bytes);
  }
};

/// What a module counts itself, beyond what the replayer measures around its handlers (processing time, queue
/// depth, and late or out-of-order inputs read from their header stamps).
struct ModuleCounters {
  int64_t dropped = 0;                ///< inputs rejected or discarded (too late to re-apply, unusable) [count]
  std::vector<std::string> warnings;  ///< e.g. "no driftlab.laser_scan_t on SCAN: no map built"
  std::vector<std::pair<std::string, double>> metrics;  ///< what else the module measured, by name with its unit
};

/// A channel a replay will deliver to its modules, known before the run: its name as delivered (after filters and
/// remaps), the driftlab type of its first message ("driftlab.laser_scan_t"; "" when not a driftlab type) and its
/// message count. Modules whose inputs are not set look here for channels of the types they take.
struct InputChannel {
  std::string name;
  std::string type;
  int64_t count = 0;
};
/// What a run delivers; empty live, where nothing is known in advance.
using InputChannels = std::vector<InputChannel>;

/// A processing module. The replayer (or a live runner) calls start() once with its bus, delivers messages to the
/// handlers the module subscribed, and calls finish() after the last message (to publish maps, final estimates).
class Module {
 public:
  virtual ~Module() = default;
  virtual std::string name() const = 0;
  /// Subscribes and prepares; an error (one line) stops the run before any message is delivered.
  virtual Status start(Bus& bus) = 0;
  virtual void finish(Bus& bus) {}
  virtual ModuleCounters counters() const { return {}; }
};

}  // namespace driftlab
