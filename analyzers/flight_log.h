// Flight-log diagnosis of a PX4 flight log (ULog) imported into a driftlab log (formats/import.h): what the flight
// controller's own log says of its timing and its estimator, beside the per-channel timing of analyzers/timing.h.
// The logger's dropouts (ULOG_DROPOUTS); the delay from sample to publication where a topic carries both
// `timestamp` and `timestamp_sample`; the regularity of the IMU's intervals (a scheduler that skips a cycle and
// catches up shows intervals of 2 periods and 0); the estimator's health over time (innovation test ratios over 1,
// rejected fusions, timeouts, IMU data it dropped). A companion computer's `timesync_status` is imported as
// driftlab.timesync_status_t and judged with every other time sync by the timing diagnosis (analyzers/timing.h,
// "timesync"), MAVROS's and PX4's alike. Topics are read by
// field name through the formats the import stores on FOREIGN_SCHEMAS (formats/ulog.h resolves them), so PX4
// versions that renamed or moved fields are read alike: each check runs on whichever of its topics the log has, and
// a field that is missing, of another type or outside a message is skipped. The thresholds that make a finding a
// problem are FlightLogThresholds'; docs/diagnosis.md ("Flight logs") says why each is what it is.
// Thread-safety: a pure function of the log.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/result.h"

namespace driftlab::analyzers {

/// When a finding becomes a problem (docs/diagnosis.md, "Flight logs").
struct FlightLogThresholds {
  /// Logger dropouts: any. Each is a stretch missing from every topic at once.
  int64_t dropouts = 1;
  /// Delay from sample to publication of a sensor topic, its p99 [s]. An IMU's (sensor_accel, sensor_gyro,
  /// vehicle_imu, sensor_combined, vehicle_angular_velocity, vehicle_acceleration) against imu_delay_p99_s: PX4's
  /// drivers publish within a cycle of sampling (under 1 ms on the shared logs); 20 ms is five 250 Hz cycles, by
  /// which everything the IMU feeds (the prediction, the rate controller) lags. Any other sensor's against the
  /// estimator's fusion horizon where the log shows it (estimator_status' timestamp - timestamp_sample), else
  /// sample_delay_p99_s, EKF2's default horizon (EKF2_GPS_DELAY, 110 ms): a sample published later reaches the
  /// estimator after it fused past the sample's time.
  double imu_delay_p99_s = 0.020;
  double sample_delay_p99_s = 0.110;
  /// IMU intervals at about 2 periods or about 0 (a skip and its catch-up), share of all intervals: a loop that
  /// keeps its period has none of either; 5% is a skip every 20 cycles, far above jitter.
  double imu_skip_share = 0.05;
  /// An interval this many periods long or more is a gap in a sensor's samples.
  double gap_periods = 2.5;
  /// Time an innovation test ratio spent over 1 (the measurement rejected), or a rejection flag was set [s]: one
  /// rejected sample is the gate doing its job; a second or more is the estimator flying without that sensor.
  double rejected_s = 1.0;
  /// Timeouts flagged by the estimator: any (a sensor it stopped hearing from).
  int64_t timeouts = 1;
  /// IMU data the estimator dropped: its time_slip grew by this much [s] (one 250 Hz sample is 4 ms).
  double time_slip_s = 0.004;
};

struct FlightDropout {
  double at_s = 0;        ///< from the log's start [s]
  double duration_s = 0;  ///< [s]
};

/// A topic with both `timestamp` (publication) and `timestamp_sample` (when the sensor sampled).
struct SampleDelay {
  std::string channel;
  std::string topic;    ///< its PX4 topic ("sensor_gyro")
  bool sensor = false;  ///< a sensor's topic (judged); estimator outputs carry the fusion horizon's sample time
  int64_t count = 0;
  double p50_s = 0, p99_s = 0, max_s = 0;  ///< timestamp - timestamp_sample [s]
  int64_t negative = 0;                    ///< published before it was sampled [count]
};

/// Intervals between an IMU topic's samples (timestamp_sample, else timestamp), against its nominal period (the
/// median interval: the rate the log holds it at).
struct ImuIntervals {
  std::string channel, topic;
  int64_t intervals = 0;
  double nominal_s = 0;
  double share_1x = 0;     ///< within 25% of the period [fraction]
  double share_2x = 0;     ///< within 25% of two periods: one skipped
  double share_0 = 0;      ///< under a quarter period (or stepping back): a sample delivered with the one before
  double share_other = 0;  ///< anything else
  double longest_s = 0;
  double longest_at_s = 0;  ///< where the longest begins, from the log's start [s]
  int64_t gaps = 0;         ///< intervals of gap_periods periods or more
};

/// A watched series of the estimator: an innovation test ratio (over 1: rejected) or a flag (set).
struct EstimatorCheck {
  std::string channel;
  std::string field;  ///< "gps_hpos[0]", "reject_hor_pos", "innovation_check_flags: vertical position"
  std::string kind;   ///< "test_ratio", "rejected", "timeout"
  int64_t samples = 0;
  int64_t over = 0;  ///< samples over 1 / set [count]
  double max = 0;    ///< largest test ratio (1 for flags set)
  /// Time over 1 / set [s]: each such sample counts until the next sample, at most two median intervals.
  double time_over_s = 0;
  double first_s = -1;  ///< the first sample over / set, from the log's start [s]; -1: none
};

/// IMU data lost on the way into the estimator, where the log says: EKF2's time_slip (the time its inertial
/// prediction fell behind), a vehicle_imu_status error count.
struct ImuLoss {
  std::string channel, field;
  double growth = 0;  ///< over the flight: [s] for time_slip, [count] for error counts
};

/// One thing on the flight's timeline.
struct FlightEvent {
  std::string kind;               ///< "dropout", "rejection", "timeout", "sensor_gap"
  std::string what;               ///< the channel and field, or "logger"
  double start_s = 0, end_s = 0;  ///< from the log's start [s]
};

/// The flight's time of day, from its GNSS receiver's UTC against the boot clock (ULOG_UTC, formats/ulog_messages.h):
/// each fix's UTC - boot time, their median the boot clock's offset to UTC.
struct FlightUtc {
  bool known = false;          ///< false: no GNSS fix with a time in the log
  int64_t boot_to_utc_us = 0;  ///< UTC = boot time + this [us]; the median of the fixes' offsets
  int64_t start_utime = 0;     ///< the log's start on the boot clock [us]: the ULog header's (ULOG_INFO's stamp)
  int64_t start_utc_us = 0;    ///< the log's start in UTC [us since 1970]
  int64_t fixes = 0;           ///< GNSS messages with a 3D fix and a time [count]
  double spread_s = 0;         ///< the largest minus the smallest offset [s]: how much the ties disagree
  std::string channel;         ///< the GNSS topic of the first tie ("vehicle_gps_position")
};

/// The UTC of log's flight; `known` false without GNSS time. Its start is the ULog header's, with which the import
/// stamps the information fields (ULOG_INFO), else `start_utime` (the log's earliest event [us]). Reads ULOG_UTC
/// and ULOG_INFO only.
FlightUtc flight_utc(const std::string& log, int64_t start_utime);

struct FlightLogDiagnosis {
  bool present = false;  ///< the log came from a ULog (or carries ULog topics)
  int64_t start_utime = 0;
  int64_t dropout_count = 0;
  double dropout_total_s = 0, dropout_max_s = 0;
  std::vector<FlightDropout> dropouts;
  std::vector<SampleDelay> sample_delays;
  /// The estimator's fusion horizon: the median timestamp - timestamp_sample of estimator_status (or
  /// estimator_innovations), the shortest over its instances [s]; 0 when the log does not say
  double horizon_s = 0;
  std::string horizon_channel;
  std::vector<ImuIntervals> imu;
  std::vector<EstimatorCheck> estimator;  ///< only series with a sample over / set, and every test ratio's max
  std::vector<ImuLoss> imu_loss;
  FlightUtc utc;
  std::vector<FlightEvent> timeline;  ///< by start time, at most 500 of each kind
  std::vector<std::string> problems;  ///< cause first, in words
};

/// Reads an LCM log (a ULog imported by driftlab import) and diagnoses the flight; `present` false, and nothing
/// else, when it carries no ULog data. An Error when the log cannot be opened.
Result<FlightLogDiagnosis> diagnose_flight_log(const std::string& log, const FlightLogThresholds& thresholds = {});

}  // namespace driftlab::analyzers
