// The replayer: merges one or more logs in time order and dispatches every event to modules (SLAM, estimator,
// controller) through the Bus they also use live, hosted as live (module_host.h) but on the virtual clock: a
// module's "now" is the time of the message it handles. Before dispatch it can filter and rename channels, correct
// clocks (restamp) and inject faults; what the modules publish goes back on the bus (to the other modules, in
// publication order) and into the output log, with per-module statistics. The same inputs and options give a
// byte-identical output log. Thread-safety: a Replayer runs on one thread; modules are called from it only.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/clock_correction.h"
#include "core/result.h"
#include "faults/faults.h"
#include "runtime/bus.h"
#include "runtime/module_host.h"

namespace driftlab::config {
template <class T>
class Table;
}

namespace driftlab::replay {

using ClockCorrection = driftlab::ClockCorrection;
/// Per channel (as named in the input logs), e.g. from `driftlab diagnose` (analyzers/clock_corrections.h).
using Restamp = ClockCorrections;

/// A restamp file: `channels: {IMU: {offset_s: 0.015, drift_ppm: 0, reference_utime: 0}}`.
struct RestampFile {
  Restamp channels;
};
/// Its keys, with units and ranges (core/config.h).
const config::Table<RestampFile>& restamp_file_table();

/// Reads a restamp file. Errors name the file, line and key.
Result<Restamp> load_restamp(const std::string& path);

enum class Order {
  kReceived,  ///< by log time (arrival at the recorder), as the robot's software saw them
  kStamp,     ///< by header stamp, re-sorted within a window; later stragglers are delivered late
};
/// "received", "stamp": as `--order` takes them.
const char* to_string(Order order);

struct ReplayOptions {
  std::vector<std::string> logs;
  std::string channels;                                   ///< ECMAScript regex of input channels; empty: all
  std::vector<std::pair<std::string, std::string>> remap; ///< input channel A is delivered as B
  Order order = Order::kReceived;
  double reorder_window_s = 0.5;  ///< how long kStamp waits for stragglers [s]
  double start_s = 0;             ///< skip the first start_s of the logs [s, from the first event]
  double end_s = std::numeric_limits<double>::infinity();  ///< stop after end_s [s, from the first event]
  Restamp restamp;                ///< clock corrections applied before dispatch
  std::optional<FaultConfig> inject;  ///< faults added at replay, before dispatch (after restamp)
  bool timing = false;            ///< measure processing time (and the queues it implies); makes the output vary
  double stats_period_s = 1.0;    ///< module statistics interval [s of log time]
  std::string out;                ///< output log; empty: none
  bool write_inputs = true;       ///< the output log holds the dispatched inputs as well as the outputs
  std::string stats_channel = "MODULE_STATS";
  std::string faults_channel = "REPLAY_FAULTS";  ///< where the manifest of injected faults goes
  /// Called now and then with the bytes of the logs read so far and their total (a progress line on a TTY).
  std::function<void(uint64_t done, uint64_t total)> progress;
};

struct ReplayReport {
  int64_t read = 0;        ///< events read from the logs (after -c, --start, --end)
  int64_t dispatched = 0;  ///< input deliveries (after injected drops and duplicates)
  int64_t outputs = 0;     ///< messages the modules published
  int64_t start_utime = 0, end_utime = 0;  ///< virtual time of the first and last delivery [us]
  uint64_t log_problems = 0;               ///< corruption met while reading
  bool interrupted = false;
  std::map<std::string, int64_t> channels;  ///< deliveries per (remapped) input channel
  std::vector<runtime::ModuleReport> modules;
  std::vector<driftlab::fault_t> injected;  ///< what --inject did
};

/// A message leaving the replayer (an input as delivered, or a module's output), for re-publication.
using Sink = std::function<void(const BusMessage&)>;

/// The channels the replay the options describe delivers to its modules (after the channel filter and --remap), with
/// the type of each one's first message and its count, sorted by name; from the logs' indexes.
InputChannels delivered_channels(const ReplayOptions& options);

/// `--remap FROM=TO`: channel FROM delivered as TO. Errors name the item.
Result<std::pair<std::string, std::string>> parse_remap(const std::string& item);

/// Refuses corrections or faults (`what`: "--restamp FILE", "--inject FILE") naming a channel none of the logs
/// has: they would change nothing, and the replay would report success as if they had (a misspelt channel, or a
/// file written for another log). The error lists up to 8 of the logs' channels.
Status refuse_absent_channels(const std::string& what, const std::vector<std::string>& channels,
                              const std::vector<std::string>& logs);

class Replayer {
 public:
  explicit Replayer(ReplayOptions options);
  ~Replayer();
  void add_module(std::unique_ptr<Module> module);

  /// Opens the logs, starts the modules and creates the output log. Errors (bad input: unreadable logs, a bad
  /// channel regex, a module that fails to start) leave no output behind. Once only; run() calls it if needed.
  Status open();
  /// Runs to the end of the logs (or until *stop). Errors: those of open(), and a write failure of the output log
  /// (which then keeps what was written, as a valid log).
  Result<ReplayReport> run(const Sink& sink = {}, const std::atomic<bool>* stop = nullptr);

 private:
  struct Prepared;
  ReplayOptions options_;
  std::unique_ptr<runtime::ModuleHost> host_;
  std::unique_ptr<Prepared> prepared_;
};

}  // namespace driftlab::replay
