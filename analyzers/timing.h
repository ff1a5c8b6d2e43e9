// Timing diagnosis of a log, from the log alone: per channel rate, drops (sequence gaps, or gaps in the period),
// duplicates, reordering, latency (arrival - header stamp) split into the source clock's offset and drift and
// the transport delay; skew between streams that observe the same motion (yaw rate), by cross-correlation.
// Never reads the injected-fault manifest. Thread-safety: pure function of the log.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "analyzers/correlation.h"
#include "core/result.h"

namespace driftlab::analyzers {

struct Distribution {
  double mean = 0, p50 = 0, p95 = 0, p99 = 0, max = 0;
};

struct Gap {
  int64_t start_utime = 0;  ///< stamp of the last message before the gap [us]
  int64_t end_utime = 0;    ///< stamp of the first message after it [us]
  int64_t missing = 0;      ///< messages missing [count]
  /// Their arrivals [us], for gaps in the period of a stream with stamps: how long a consumer went without; 0
  /// otherwise
  int64_t start_arrival = 0, end_arrival = 0;
};

/// What a reason says is wrong, cause before symptom: a clock on the wrong time base or running ahead explains the
/// reordering and rejections it leads to; a late stream or loop explains the stale data; loss explains holes; data
/// that does not decode; and the symptoms (reordering, bursts, spikes) last. A channel's reasons are listed in this
/// order, and the worst stream is the one whose first reason ranks highest (docs/diagnosis.md, "The headline").
enum class Cause : int8_t { kClock, kLate, kLoss, kData, kSymptom };
/// "clock", "late", "loss", "data", "symptom": the JSON's words.
const char* cause_name(Cause c);
/// The Cause a word names (a symptom for any other word).
Cause cause_from_name(std::string_view name);
/// How bad a stream's findings are, to name the worst stream first: faults before warnings, then the deeper first
/// cause, then the more reasons; 0 for a stream that is ok.
int problem_rank(std::string_view verdict, Cause first_cause, size_t reasons);

struct ChannelTiming {
  std::string name;
  std::string type;                 ///< "driftlab.imu_t", or "" when unknown
  std::string source_type;          ///< its type in the recording it was imported from ("nav_msgs/msg/Odometry"), or ""
  bool has_header = false;          ///< seq and stamps were read from driftlab.header_t
  /// seq was counted by the import, not sent by the source (ROS 2 headers carry none): drops are told from the
  /// stamps' period
  bool seq_counted = false;
  /// A result written at once, not a stream: stamps spanning 10 s or more, every message arriving within 1% of that
  /// (a SLAM's whole trajectory as last optimised, written at the end). No latency, clock or period is judged.
  bool written_at_once = false;
  int domain = -1;  ///< its stamps' clock: an index into Diagnosis::domains (-1: no header, or unset)
  /// How much later than the fastest of its clock's streams its messages arrive: the median over windows of its
  /// fastest delivery against theirs [s]; NaN when its clock has no other stream
  double peer_delay_s = std::numeric_limits<double>::quiet_NaN();
  int64_t count = 0;
  int64_t malformed = 0;            ///< messages that do not hold their type's layout (left out of the rest) [count]
  std::string malformed_example;    ///< why the first of them is malformed
  double rate_hz = 0;               ///< messages per second of arrival time
  double expected_period_s =
      0;  ///< median interval between stamps (arrivals without a header); the mean one when bursty or irregular
  bool irregular = false;           ///< no period: under a third of the intervals within 25% of the median one
  double regular_fraction = 0;      ///< the intervals within 25% of the median one [fraction]
  bool bursty = false;              ///< messages come in groups (median interval under a quarter of the mean)
  double burst_size = 0;            ///< when bursty: the median number of messages in a group [count]
  double burst_interval_s = 0;      ///< when bursty: the median interval, inside the groups [s]
  int64_t seq_gaps = 0;             ///< messages missing from gaps in seq [count]
  int64_t missing_by_period = 0;    ///< messages missing from gaps in time longer than 1.5 periods [count]
  std::vector<Gap> gaps;            ///< seq gaps with a header, time gaps without
  int64_t duplicates = 0;           ///< extra copies of a message already received (same seq; without a header, the same bytes again within a quarter period) [count]
  int64_t out_of_order_stamp = 0;   ///< messages whose stamp is older than an earlier-arrived one [count]
  int64_t out_of_order_arrival = 0; ///< log timestamps that step back [count]
  int64_t repeated_stamps = 0;      ///< messages (of another seq) stamped exactly like the one before: frozen stamps [count]
  int64_t zero_stamps = 0;          ///< messages stamped 0: never set [count]
  int64_t median_stamp_utime = 0;   ///< the median stamp [us], to tell simulation time from wall-clock dates
  /// arrival - stamp [s]; for a stream on a clock of its own (simulation time, time since boot), arrival - the
  /// stamp mapped to the recorder's clock through its domain (clock_domains): the latency above its domain's fastest
  Distribution latency_s;
  bool latency_valid = false;       ///< latency measured: stamps set (not 0), and not static transforms
  bool clock_valid = false;         ///< enough data spread over time to fit the clock
  double clock_offset_s = 0;        ///< source clock ahead of the recorder's at the log's start [s] (fastest delivery taken as instantaneous)
  double clock_drift_ppm = 0;       ///< source clock running fast [ppm]
  std::array<double, 2> clock_offset_ci_s{};    ///< 95% confidence interval of clock_offset_s [s]
  std::array<double, 2> clock_drift_ci_ppm{};   ///< 95% confidence interval of clock_drift_ppm [ppm]
  int64_t late_stamps = 0;          ///< stamps later than the channel's usual latency allows (left out of the clock fit) [count]
  double first_late_stamp_s = 0;    ///< the first of them, from the log's start [s]
  double late_stamp_max_s = 0;      ///< how much later than the median latency the latest of them is [s]
  Distribution transport_s;         ///< latency above the fitted clock line [s]
  std::string verdict = "ok";       ///< ok, warn or fault
  std::vector<std::string> reasons;  ///< why, in words, cause before symptom
  std::vector<Cause> causes;         ///< what each reason says is wrong (parallel to reasons)
};

/// A clock that the stamps of some streams share (docs/diagnosis.md, "Clock domains"): the recorder's own (the
/// log's event times), or one of its own, as simulation time under use_sim_time, a flight controller's time since
/// boot, GPS time or TAI. The streams of a foreign clock are judged against its mapping to arrival, fitted to the
/// fastest deliveries of its streams (of transforms only when nothing else is there, as they may be post-dated on
/// purpose).
struct ClockDomain {
  /// "recorder", "simulation", "boot_or_simulation" (stamps from near zero at real-time rate), "gps" (GPS time
  /// against UTC), "gps_epoch" (seconds since 1980-01-06), "tai", "time_zone", "other"
  std::string kind;
  std::string description;            ///< in words
  std::vector<std::string> channels;  ///< its streams
  double offset_s = 0;                ///< median arrival - stamp of its streams [s]
  /// Its streams are judged through its mapping: another epoch (more than a day from the log's times: simulation
  /// time, time since boot). Otherwise against arrival as stamped: the recorder's clock, or one set wrong by
  /// seconds to hours (GPS time, TAI, a time zone), whose offset is a clock's that a replay can correct.
  bool mapped = false;
  bool rate_valid = false;  ///< a foreign clock seen over 10 s or more of arrivals
  double rate = 1;          ///< its seconds per second of the recorder's clock (a simulation's real-time factor)
  double rate_min = 1, rate_max = 1;  ///< the same over 10 s windows of arrivals
  /// What its streams are judged against: a simulator's clock channel recorded with them (/clock, whose stamps
  /// are the simulation's time as it ticked), or "" for its fastest streams' deliveries (without /clock, latency
  /// has no absolute zero on a clock of another epoch).
  std::string reference;
  /// A mapped clock's mapping to arrival: knots (stamp [s], arrival - stamp [s]), by stamp, read with
  /// mapped_offset_s; empty for the recorder's clock and clocks judged as stamped.
  std::vector<std::array<double, 2>> mapping;
};

/// arrival - stamp on a domain's mapping at a stamp [s]: linear between its knots, and beyond the ends along the
/// first or last two (a knot is a window's fastest delivery, usually at one end of its window: a real-time
/// factor's slope goes on past it); 0 without knots.
double mapped_offset_s(const std::vector<std::array<double, 2>>& knots, double stamp_s);

struct SkewWindow {
  double start_s = 0, end_s = 0;   ///< relative to the start of the log [s]
  double offset_s = 0, confidence = 0;
};

struct StreamPair {
  std::string a, b;
  double offset_s = 0;     ///< how much later b's stamps are than a's for the same physical instant [s]
                           ///< (the confidence-weighted median over the windows)
  std::array<double, 2> offset_ci_s{};  ///< 95% confidence interval of offset_s: the windows' offsets [s]
  double confidence = 0;                ///< 0..1: the windows' median peak correlation times their agreement (the
                                        ///< correlation-weighted share of windows within 2 ms of offset_s)
  std::string method;      ///< "yaw-rate cross-correlation"
  std::vector<SkewWindow> windows;
  /// (lag [s], correlation) every 10 ms of lag over the search range, the windows' confidence-weighted mean
  std::vector<std::pair<double, double>> curve;
  /// A skew driftlab names: its motions match and its windows agree (analyzers/correlation.h). The others are kept
  /// with their curves, unsure.
  bool confident() const { return confidence >= kConfidentCorrelation; }
};

/// How the stamps of a dynamic transform meet those of a channel whose data is composed with it (the transforms
/// between the data's frame and the root of the tree: `map -> odom` for odometry in `odom`), at the time the data
/// is used: when each message arrives, how far its stamp lies beyond the newest transform received, i.e. how far a
/// lookup at its stamp would extrapolate into the future, and how long it waits for a transform as new.
struct TfStampCheck {
  std::string parent, child;  ///< the transform
  std::string tf_channel;     ///< the channel that carries it (the first one seen)
  std::string channel;        ///< the data's channel
  std::string frame;          ///< the data's frame (the transform's child: composed with it directly)
  int64_t messages = 0;       ///< data messages that arrived after the transform's first [count]
  double period_s = 0;        ///< the transform's median interval between stamps [s]
  /// Data stamp - the newest transform stamp received at the data's arrival [s]: up to a period of the transform
  /// when both are stamped alike (data arriving just before the next transform), more when the transform is
  /// stamped behind the data or arrives late; below zero when it is stamped ahead (post-dated, as AMCL's
  /// transform_tolerance does on purpose).
  Distribution lead_s;
  /// The lead's lower envelope (its 1st percentile): how far the transform's stamps lag the data's even right
  /// after one arrives, which no period explains [s]. About 0 when both are stamped alike.
  double offset_s = 0;
  /// From a message's arrival until a transform as new as its stamp arrives [s] (0 when one already had).
  Distribution wait_s;
  /// Median arrival - stamp of the transform and of the data [s]: which of the two the offset comes from (a clock
  /// behind, a stamp taken early and a slow transport look alike in one log).
  double tf_latency_s = 0, data_latency_s = 0;
  int64_t never = 0;  ///< messages no transform as new as their stamp ever reached [count]
};

/// One transform of the TF tree, parent -> child, as tf2's view_frames lists it: who broadcasts it, how often, how
/// old it is when it arrives.
struct TfEdge {
  std::string parent, child;
  std::string channel;  ///< the channel that carried it first
  bool is_static = false;
  int64_t count = 0;         ///< transforms received [count]
  double rate_hz = 0;        ///< by their distinct stamps (0 when static)
  int64_t out_of_order = 0;  ///< stamped older than one of the same transform already received [count]
  /// arrival - stamp, the stamp on the recorder's clock (through its clock domain) [s]: below zero, post-dated
  Distribution age_s;
  int64_t ahead = 0;  ///< stamped more than 1 ms ahead of their arrival [count]
};

/// The TF tree seen in the log (channels of driftlab.tf_t; a channel whose name contains "static", in any case,
/// holds static transforms) and what would go wrong when data is transformed with it.
struct TfDiagnosis {
  std::vector<std::string> frames;    ///< every frame, sorted
  std::vector<std::string> roots;     ///< frames that are nobody's child
  std::vector<TfEdge> edges;          ///< every transform, by child frame
  std::vector<TfStampCheck> stamps;   ///< per data channel and dynamic transform it is composed with
  std::vector<std::string> problems;  ///< in words
};

/// A command loop seen in the log: a channel of joint trajectories (driftlab.joint_trajectory_t) and the joint
/// states (driftlab.joint_state_t) of the same joints. The delay from command to motion is measured from the
/// motion itself (a late command may carry an honest stamp): the lag at which the measured joint positions (at
/// their stamps) best repeat the commanded ones (each command's plan, from its stamp, until the next command's).
struct CommandLoop {
  std::string command_channel, state_channel;
  int64_t commands = 0;
  double command_period_s = 0;  ///< median interval between the commands' stamps [s]
  bool delay_valid = false;     ///< confidence 0.5 or more: one delay the motion shows throughout
  double delay_s = 0;           ///< the measured joints follow the commanded motion this much later [s]
  /// The agreement at the delay (1 - mean squared difference / variance; 1: the same motion) times the share of the
  /// log's thirds whose own delay is within 5 ms of it (a drifting clock's delay grows along the log)
  double confidence = 0;
  /// Commands whose whole plan lay in the past when they arrived (stamp + last point's time < arrival): a
  /// controller that honours stamps discards them, one that does not runs a plan that is over.
  int64_t stale = 0;
  double first_stale_s = 0;                      ///< when the first stale one arrived, from the start of the log [s]
  double stale_max_s = 0;                        ///< how long its plan had been over when the worst one arrived [s]
  std::vector<std::pair<double, double>> curve;  ///< (lag [s], agreement) over the lags searched, for plots
};

/// A simulator's own step times (driftlab.physics_step_t, as Gazebo's performance metrics): how much slower than
/// real time it ran. A lockstep simulation slower than the wall clock delivers every stream at that fraction of its
/// rate to anything on the wall clock, and its stamps (simulated time) fall behind the wall clock's.
struct PhysicsTiming {
  std::string channel;
  int64_t messages = 0;
  double real_time_factor_mean = 1;  ///< simulated over wall-clock time, over the log
  double real_time_factor_min = 1;
  double sim_step_s = 0;       ///< simulated time per physics update [s]
  double wall_step_max_s = 0;  ///< the longest an update took on the wall clock [s]
};

/// A time synchronisation between two computers (driftlab.timesync_status_t: MAVROS's companion <-> flight
/// controller): how long its exchanges took, where its offset estimate went, and how often it started over.
struct TimesyncTiming {
  std::string channel;
  int64_t messages = 0;
  Distribution round_trip_s;  ///< the exchanges' round trips [s]
  double offset_first_s = 0;  ///< the estimated offset (remote - local) at the first message [s]
  double offset_last_s = 0;   ///< and at the last [s]
  double offset_min_s = 0, offset_max_s = 0;
  /// Steps of the estimated offset over kResyncStep_s from one message to the next: the filter started over (a
  /// remote clock that jumped or a link that stalled); the first ones' times from the log's start [s]
  int64_t resyncs = 0;
  std::vector<double> resync_at_s;
  Distribution residual_s;  ///< |observed - estimated offset|: how much each exchange disagrees with the estimate [s]
};

struct Diagnosis {
  std::string log;
  int64_t start_utime = 0, end_utime = 0;
  std::vector<ChannelTiming> channels;
  std::vector<ClockDomain> domains;  ///< the clocks the streams' stamps are on
  std::vector<StreamPair> pairs;
  TfDiagnosis tf;
  std::vector<CommandLoop> command_loops;
  std::vector<PhysicsTiming> physics;  ///< per channel of driftlab.physics_step_t
  std::vector<TimesyncTiming> timesync;  ///< per channel of driftlab.timesync_status_t
  uint64_t log_problems = 0;  ///< corruption met while reading
  /// The log carries a PX4 flight log's records (ULOG_* channels, written by `driftlab import` of a .ulg): its
  /// flight-log diagnosis (analyzers/flight_log.h) has something to say
  bool flight_log = false;
  /// How many stretches of the log were read, each on its own thread (1: one pass from the start, as on a short
  /// or damaged log). Nothing else depends on it.
  int stretches = 1;
};

struct DiagnoseOptions {
  double max_lag_s = 0.3;    ///< skew search range [s]
  double window_s = 10.0;    ///< skew window [s] (longer on long logs: at most 64 windows)
  /// Bookkeeping, not streams: the recorder's and the replayer's statistics (one seq per module, so they would
  /// look duplicated) and the fault manifests; an import's records: what it says of channels and schemas, a PX4
  /// flight log's text, parameters, information fields, its logger's dropouts and its GNSS receiver's UTC against
  /// the boot clock (records at a time, not streams).
  std::vector<std::string> ignore_channels = {
      "CHANNEL_SOURCES", "DRIFTLAB_RECORDER_STATS", "FAULTS",    "FOREIGN_SCHEMAS", "MODULE_STATS", "REPLAY_FAULTS",
      "SIMULATION",      "ULOG_DROPOUTS",           "ULOG_INFO", "ULOG_LOG",        "ULOG_PARAMS",  "ULOG_UTC"};
  /// Only the channels fully matching this ECMAScript regex (as lcm-logger's -c), and the bookkeeping channels
  /// above, which say how to read them; empty: every channel.
  std::string channels;
  /// Threads reading the log, each a stretch of it (0: one per core, on logs of 64 MB a stretch or more). The
  /// diagnosis is the same whatever the number.
  int pass_threads = 0;
};

Result<Diagnosis> diagnose(const std::string& log, const DiagnoseOptions& options = {});

}  // namespace driftlab::analyzers
