// The fault model shared by the simulator and the replayer: what a real system would see when a stream's source
// clock is offset or drifts, its transport is slow, jittery or lossy (independent or bursty drops), or duplicates
// and reorders messages. Faults are described per channel in YAML (docs/faults.md) and every injected fault is
// reported in a manifest (driftlab.fault_manifest_t) so tests can score the diagnosis.
// Thread-safety: a StreamFaultInjector belongs to one thread; FaultConfig is a plain value.
#pragma once

#include <cstdint>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "core/result.h"
#include "driftlab/fault_manifest_t.hpp"

namespace driftlab {

namespace config {
template <class T>
class Table;
}

/// Faults on one stream; every field is optional (0: off).
struct StreamFaults {
  double clock_offset_s = 0;         ///< the source clock is ahead of true time by this much [s]
  double clock_drift_ppm = 0;        ///< the source clock runs fast by this much [ppm] (from the start of the run)
  double latency_s = 0;              ///< transport delay, fixed part [s]
  double jitter_s = 0;               ///< transport delay, random part: exponential with this mean [s]
  double drop_probability = 0;       ///< each message lost independently with this probability
  double burst_enter = 0;            ///< Gilbert-Elliott burst loss: probability, per message, of entering a burst
  double burst_exit = 0;             ///< ... and of leaving it; every message in a burst is lost
  double duplicate_probability = 0;  ///< each message delivered twice with this probability
  double reorder_probability = 0;    ///< each message held back by reorder_delay_s with this probability
  double reorder_delay_s = 0.05;     ///< how long a reordered message is held back [s]
};

struct FaultConfig {
  uint64_t seed = 0;
  std::map<std::string, StreamFaults> streams;  ///< by channel
};

/// The keys of a stream's faults and of a fault description (`seed:` and `streams: {CHANNEL: {key: value}}`), with
/// their units and ranges (core/config.h): how they are read, and their reference.
const config::Table<StreamFaults>& stream_faults_table();
const config::Table<FaultConfig>& fault_config_table();

/// Parses the YAML fault description; errors say "ORIGIN:LINE: ..." and name the key.
Result<FaultConfig> parse_faults(const std::string& yaml_text, const std::string& origin);
Result<FaultConfig> load_faults(const std::string& path);

/// One delivery of a message: its stamp in the source clock and its arrival in the true clock.
struct Delivery {
  int64_t stamp_utime = 0;    ///< header.utime as the source writes it [us]
  int64_t arrival_utime = 0;  ///< when it reaches the recorder [us, true clock]
};

/// Applies a stream's faults, deterministically for a seed, and remembers what it did for the manifest.
class StreamFaultInjector {
 public:
  /// start_utime: the start of the run [us, true clock], from which clock drift accumulates.
  StreamFaultInjector(std::string channel, StreamFaults faults, uint64_t seed, int64_t start_utime);

  /// The deliveries of message seq measured at true time true_utime [us]: none when dropped, two when duplicated.
  /// Deliveries may arrive out of order across messages: the caller sorts by arrival.
  void apply(int64_t seq, int64_t true_utime, std::vector<Delivery>& out);

  /// The source clock's reading at a true time [us].
  int64_t source_clock(int64_t true_utime) const;

  /// What was injected: one fault_t per kind in effect, with the seqs it dropped, duplicated or reordered.
  std::vector<driftlab::fault_t> manifest(int64_t end_utime) const;

 private:
  std::string channel_;
  StreamFaults f_;
  int64_t start_utime_;
  std::mt19937_64 rng_;
  bool in_burst_ = false;
  std::vector<int64_t> dropped_, burst_dropped_, duplicated_, reordered_;
};

}  // namespace driftlab
