// The stream header's byte layout, in one place. Every stream message starts with driftlab.header_t, and LCM
// encodes it big-endian right after the type fingerprint:
//   int64 fingerprint | int64 seq | int64 utime | int32 length of frame_id with its NUL | frame_id | NUL
// The functions here read (and rewrite) those fields in place, without decoding the whole message, for the
// analyzers, the replayer and the report. Other programs' types may start with the same header; they are
// recognised by its shape. Thread-safety: pure functions.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace driftlab::lcmtypes {

inline constexpr size_t kHeaderSeqOffset = 8;
inline constexpr size_t kHeaderStampOffset = 16;
inline constexpr size_t kHeaderFrameOffset = 24;  ///< the frame_id's length, then its bytes
/// The shortest encoded message that can hold a header (an empty frame_id is its NUL alone).
inline constexpr size_t kMinHeaderBytes = kHeaderFrameOffset + 4 + 1;

struct StreamHeader {
  int64_t seq = 0;
  int64_t utime = 0;           ///< the source's stamp [us]
  std::string_view frame_id;   ///< a view into the message
};

/// Whether a message of an unknown type starts, after its fingerprint, with driftlab.header_t: a non-negative
/// seq below 2^48, a stamp within a day of its arrival [us] (any int64 is safe), and a NUL-terminated frame name
/// of at most 255 bytes inside the message.
bool looks_like_header(std::span<const uint8_t> data, int64_t arrival_utime);

/// Whether a message carries the header: by the type registry for driftlab's types (and the message is long
/// enough), by its shape (looks_like_header) for others.
bool has_header(std::span<const uint8_t> data, int64_t arrival_utime);

/// The header of a message that has one (has_header), read in place; nullopt when it has none.
std::optional<StreamHeader> read_header(std::span<const uint8_t> data, int64_t arrival_utime);

/// The header stamp [us] of a message that has one; nullopt otherwise.
std::optional<int64_t> header_stamp(std::span<const uint8_t> data, int64_t arrival_utime);

/// Rewrites every header stamp of an encoded message with f (a tf_t's transforms carry stamps of their own and are
/// rewritten too). False, with bytes untouched, when the message has no header or does not decode.
bool map_stamps(std::vector<uint8_t>& bytes, int64_t arrival_utime, const std::function<int64_t(int64_t)>& f);

/// How long after its header stamp a message's data was complete [us]: a laser scan's sweep to its last beam
/// (scans stamp their first); 0 for other types and for scans without a usable time_increment.
int64_t ready_after_us(std::span<const uint8_t> data);

/// The motion a message observes, for skew and latency analysis.
struct Motion {
  double stamp_s = 0;    ///< the header stamp [s]
  double value = 0;      ///< yaw rate [rad/s] (imu_t, odometry_t), or yaw [rad] for a pose_t
  bool is_pose = false;  ///< value is a yaw: the caller differentiates consecutive poses
};

/// For an encoded driftlab.imu_t or odometry_t its stamp and yaw rate, for a pose_t its stamp and yaw; nullopt
/// for other types and for data too short for its fields. Reads the fields in place.
std::optional<Motion> read_motion(std::span<const uint8_t> data);

}  // namespace driftlab::lcmtypes
