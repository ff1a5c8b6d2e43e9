// PX4 topics (ULog data messages) onto driftlab's messages where driftlab has the same quantity: sensor_combined
// and vehicle_imu -> imu_t, sensor_gps / vehicle_gps_position -> gnss_t, vehicle_local_position -> odometry_t,
// vehicle_attitude -> pose_t (its orientation), sensor_baro -> barometer_t, sensor_mag and vehicle_magnetometer ->
// magnetometer_t, vehicle_odometry -> odometry_t, actuator_motors -> motor_command_t, trajectory_setpoint and
// vehicle_local_position_setpoint -> trajectory_setpoint_t, vehicle_status -> vehicle_status_t, timesync_status (and
// the older timesync) -> timesync_status_t. Fields are found by name
// in the message's own format, so PX4 versions that moved or added fields convert alike; a format without the fields a
// mapping needs is carried as foreign_message_t instead. header.utime is the message's `timestamp_sample` when it has
// one (when the sensor sampled), else its `timestamp`. Thread-safety: plain functions.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "formats/ulog.h"

namespace driftlab::formats {

struct UlogConverted {
  const char* type = "";  ///< "driftlab.imu_t"
  std::vector<uint8_t> lcm;
};

/// The driftlab type topic `name` maps onto, or nullptr when it has none.
const char* driftlab_type_for_ulog(std::string_view name);

/// Converts one data message of a mapped topic (payload: its bytes after the msg_id); nullopt when the topic has
/// no mapping or its format lacks a field the mapping needs. seq: the count of messages on its channel before it.
std::optional<UlogConverted> convert_ulog_message(const UlogLayout& layout, std::span<const uint8_t> payload,
                                                  uint64_t timestamp, int64_t seq);

/// A GNSS receiver's UTC against the flight controller's boot clock, from one sensor_gps / vehicle_gps_position
/// message: `time_utc_usec` (UTC [us since 1970]) at `timestamp + timestamp_time_relative` (boot [us]; PX4 says so
/// in vehicle_gps_position.msg; timestamp alone where the format has no timestamp_time_relative).
struct UlogUtcTie {
  int64_t boot_us = 0;
  int64_t utc_us = 0;
};
/// The tie of a GNSS message with a 3D fix (fix_type 3 and up: the receiver has solved its clock) and a UTC time;
/// nullopt for another topic, no fix, a time of 0 (not known) or a format without those fields.
std::optional<UlogUtcTie> ulog_gnss_utc(const UlogLayout& layout, std::span<const uint8_t> payload, uint64_t timestamp);

/// The channel on which `driftlab import` writes each tie, as driftlab.timesync_status_t: header.utime the boot
/// time, remote_utime the UTC time, both offsets (UTC - boot) [s], round_trip_s 0 (a receiver's time, no exchange),
/// header.frame_id the GNSS topic's channel.
inline constexpr char kUlogUtcChannel[] = "ULOG_UTC";

/// One topic's mapping resolved once for all of its messages: the mapping chosen by the format's name, each field
/// the mapping reads found by name at its first use (convert_ulog_message and ulog_gnss_utc look them all up per
/// message). The same results, message for message. Thread-safety: one converter per thread.
class UlogConverter {
 public:
  explicit UlogConverter(std::shared_ptr<const UlogLayout> layout);
  UlogConverter(UlogConverter&&) noexcept;
  UlogConverter& operator=(UlogConverter&&) noexcept;
  ~UlogConverter();

  /// Whether the topic has a mapping (driftlab_type_for_ulog).
  bool mapped() const;
  /// convert_ulog_message's message encoded into *out (its memory kept from one message to the next): its driftlab
  /// type, or nullptr where convert_ulog_message gives nullopt (*out then holds nothing of use).
  const char* convert(std::span<const uint8_t> payload, uint64_t timestamp, int64_t seq,
                      std::vector<uint8_t>* out) const;
  /// ulog_gnss_utc of the message.
  std::optional<UlogUtcTie> gnss_utc(std::span<const uint8_t> payload, uint64_t timestamp) const;

 private:
  struct Plan;
  std::unique_ptr<Plan> plan_;
};

}  // namespace driftlab::formats
