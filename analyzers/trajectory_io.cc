#include "analyzers/trajectory_io.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "analyzers/internal/number_lines.h"
#include "core/log_format.h"
#include "core/log_index.h"
#include "core/log_reader.h"
#include "core/mapped_file.h"
#include "core/number_text.h"
#include "core/text_file.h"
#include "core/time.h"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/trajectory_setpoint_t.hpp"
#include "lcmtypes/validate.h"

namespace driftlab::analyzers {
namespace {

std::string_view text_of(const MappedFile& f) {
  const auto bytes = f.bytes();
  return {reinterpret_cast<const char*>(bytes.data()), bytes.size()};
}

void reserve(Trajectory& t, size_t n) {
  t.stamps.reserve(n);
  t.positions.reserve(n);
  t.orientations.reserve(n);
}

/// Reads the poses of a text trajectory file: parse(line_number, numbers, count, t) appends one pose or returns an
/// error (without the file and line, which this adds). `columns` numbers are kept of each line; `exact`: a line
/// must have exactly that many, else at least that many. `what` names the line format in messages.
template <typename F>
Result<Trajectory> read_lines(const std::string& path, int columns, bool exact, const char* what, size_t bytes_per_line,
                              F&& parse) {
  auto mapped = MappedFile::open(path);
  if (!mapped) return mapped.error();
  const std::string_view text = text_of(*mapped);
  Trajectory t;
  reserve(t, text.size() / bytes_per_line + 16);  // one allocation rather than doublings
  std::string error;
  constexpr int kMax = 32;
  internal::for_each_data_line(text, [&](size_t line, const char* p, const char* eol) {
    double v[kMax];
    const int n = internal::parse_numbers(p, eol, v, exact ? columns : kMax);
    std::string problem;
    if (n < 0) {
      problem = "not a number";
    } else if (exact ? n != columns : n < columns) {
      problem = std::string("expected ") + (exact ? "" : "at least ") + std::to_string(columns) + " numbers (" + what +
                "), found " + (n > columns ? "more" : std::to_string(n));
    } else {
      problem = parse(v, t);
    }
    if (!problem.empty()) error = path + ":" + std::to_string(line) + ": " + problem;
    return problem.empty();
  });
  if (!error.empty()) return Error{error};
  if (t.size() == 0) return Error{path + ": no poses (expected lines of \"" + what + "\")"};
  return t;
}

std::string short_value(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

/// The first data line of a text file, and whether the file starts with an EuRoC-style "#timestamp" header.
TrajectoryFormat detect(const std::string& path, std::string& why) {
  auto mapped = MappedFile::open(path);
  if (!mapped) {
    why = mapped.error().message;
    return TrajectoryFormat::kAuto;
  }
  const std::string_view text = text_of(*mapped);
  if (text.starts_with("#timestamp") || text.starts_with("\xEF\xBB\xBF#timestamp")) return TrajectoryFormat::kEuroc;
  int numbers = -2;
  bool commas = false;
  size_t where = 0;
  internal::for_each_data_line(text, [&](size_t line, const char* p, const char* eol) {
    double v[32];
    numbers = internal::parse_numbers(p, eol, v, 31);
    commas = std::find(p, eol, ',') != eol;
    where = line;
    return false;
  });
  if (numbers == 8) return TrajectoryFormat::kTum;
  if (numbers == 12) return TrajectoryFormat::kKitti;
  if (numbers > 8 && commas) return TrajectoryFormat::kEuroc;
  why = path + (numbers == -2 ? ": no data lines"
                              : ":" + std::to_string(where) + ": " +
                                    (numbers < 0 ? std::string("not a number")
                                                 : std::to_string(numbers) + " numbers on the first data line")) +
        ", not a trajectory evo reads (TUM: 8 numbers a line, KITTI: 12, EuRoC: comma-separated with a #timestamp "
        "header)";
  return TrajectoryFormat::kAuto;
}

}  // namespace

const char* to_string(TrajectoryFormat format) {
  switch (format) {
    case TrajectoryFormat::kAuto: return "auto";
    case TrajectoryFormat::kTum: return "tum";
    case TrajectoryFormat::kKitti: return "kitti";
    case TrajectoryFormat::kEuroc: return "euroc";
  }
  return "auto";
}

std::string pose_problem(double stamp, const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
  if (!std::isfinite(stamp) || !p.allFinite() || !q.coeffs().allFinite()) return "a number is not finite";
  const double norm = q.norm();
  if (norm < 1e-9) return "the quaternion is zero";
  if (!unit_norm(q.w(), q.x(), q.y(), q.z()))
    return "the quaternion's norm is " + short_value(norm) + ", not 1: not a rotation";
  return "";
}

Result<Trajectory> load_tum(const std::string& path) {
  // About 60 bytes a line.
  return read_lines(path, 8, true, "t x y z qx qy qz qw", 48, [](const double* v, Trajectory& t) {
    const Eigen::Vector3d p(v[1], v[2], v[3]);
    const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    std::string problem = pose_problem(v[0], p, q);
    if (problem.empty()) t.push_back(v[0], p, q);
    return problem;
  });
}

Result<Trajectory> load_euroc(const std::string& path) {
  // About 200 bytes a line (17 columns).
  return read_lines(path, 8, false, "timestamp [ns], x, y, z, qw, qx, qy, qz, ...", 160, [](const double* v, Trajectory& t) {
    // Nanoseconds to seconds as evo does (the stamp parsed to the nearest double, then divided).
    const double stamp = v[0] / 1e9;
    const Eigen::Vector3d p(v[1], v[2], v[3]);
    const Eigen::Quaterniond q(v[4], v[5], v[6], v[7]);
    std::string problem = pose_problem(stamp, p, q);
    if (problem.empty()) t.push_back(stamp, p, q);
    return problem;
  });
}

Result<Trajectory> load_kitti(const std::string& path, const std::string& times) {
  auto poses = read_lines(
      path, 12, true, "r11 r12 r13 tx r21 r22 r23 ty r31 r32 r33 tz", 150, [](const double* v, Trajectory& t) -> std::string {
        if (!std::all_of(v, v + 12, [](double x) { return std::isfinite(x); })) return "a number is not finite";
        Eigen::Matrix3d r;
        r << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
        // A rotation matrix within the rounding of printed digits: orthonormal and right-handed.
        const double off = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
        if (off > 0.01 || r.determinant() < 0) {
          return "the 3x3 part is not a rotation (R^T R differs from the identity by " + short_value(off) +
                 ", determinant " + short_value(r.determinant()) + ")";
        }
        t.push_back(static_cast<double>(t.size()), Eigen::Vector3d(v[3], v[7], v[11]), Eigen::Quaterniond(r).normalized());
        return "";
      });
  if (!poses) return poses;
  Trajectory& t = *poses;
  if (times.empty()) {
    t.stamped = false;
    return poses;
  }
  auto stamps = read_lines(times, 1, true, "t", 12, [](const double* v, Trajectory& s) -> std::string {
    if (!std::isfinite(v[0])) return "a number is not finite";
    s.push_back(v[0], Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity());
    return "";
  });
  if (!stamps) return stamps.error();
  if (stamps->size() != t.size()) {
    return Error{times + ": " + std::to_string(stamps->size()) + " stamps for the " + std::to_string(t.size()) +
                 " poses of " + path + " (one a line, as many as poses)"};
  }
  t.stamps = std::move(stamps->stamps);
  return poses;
}

bool append_pose(std::span<const uint8_t> data, Trajectory& t, std::string* why) {
  const int64_t fp = logfmt::fingerprint(data);
  auto add = [&](const auto& m) {
    const double stamp = Time::from_us(m.header.utime).seconds();
    const Eigen::Vector3d p(m.position.x, m.position.y, m.position.z);
    const Eigen::Quaterniond q(m.orientation.w, m.orientation.x, m.orientation.y, m.orientation.z);
    std::string problem = pose_problem(stamp, p, q);
    if (!problem.empty()) {
      if (why != nullptr) *why = std::move(problem);
      return false;
    }
    t.push_back(stamp, p, q);
    return true;
  };
  auto undecodable = [&](const char* type) {
    if (why != nullptr) *why = std::string("does not decode as ") + type;
    return false;
  };
  if (fp == driftlab::pose_t::getHash()) {
    driftlab::pose_t pose;
    return lcmtypes::decode(data, pose) ? add(pose) : undecodable("driftlab.pose_t");
  }
  if (fp == driftlab::odometry_t::getHash()) {
    driftlab::odometry_t odom;
    return lcmtypes::decode(data, odom) ? add(odom) : undecodable("driftlab.odometry_t");
  }
  if (fp == driftlab::trajectory_setpoint_t::getHash()) {
    // A setpoint is a position and a heading: the pose it asks for, level, turned by yaw about z.
    driftlab::trajectory_setpoint_t sp;
    if (!lcmtypes::decode(data, sp)) return undecodable("driftlab.trajectory_setpoint_t");
    if (!std::isfinite(sp.yaw)) {
      if (why != nullptr) *why = "a number is not finite";
      return false;
    }
    struct {
      driftlab::header_t header;
      driftlab::vector3_t position;
      driftlab::quaternion_t orientation;
    } pose{sp.header, sp.position, {std::cos(sp.yaw / 2), 0, 0, std::sin(sp.yaw / 2)}};
    return add(pose);
  }
  if (why != nullptr) *why = "is not a driftlab.pose_t, odometry_t or trajectory_setpoint_t";
  return false;
}

Result<Trajectory> load_log_channel(const std::string& log, const std::string& channel) {
  auto reader = LogReader::open(log);
  if (!reader) return reader.error();
  Trajectory t;
  Event e;
  bool seen = false;
  while (reader->next(e)) {
    if (e.channel != channel) continue;
    seen = true;
    const int64_t fp = logfmt::fingerprint(e.data);
    if (fp != driftlab::pose_t::getHash() && fp != driftlab::odometry_t::getHash() &&
        fp != driftlab::trajectory_setpoint_t::getHash()) {
      return Error{log + ": channel " + channel +
                   " carries no poses: not a driftlab.pose_t, odometry_t or trajectory_setpoint_t (event at byte " +
                   std::to_string(e.offset) + ")"};
    }
    if (std::string why; !append_pose(e.data, t, &why)) {
      return Error{log + ": event at byte " + std::to_string(e.offset) + " on " + channel + ": " + why};
    }
  }
  if (!seen) {
    std::string known;
    if (auto index = LogIndex::load_or_build(log); index.ok()) {
      for (const auto& c : index->summary().channels) known += (known.empty() ? "" : ", ") + c.name;
    }
    return Error{log + ": no channel " + channel + " (channels: " + (known.empty() ? "none" : known) + ")"};
  }
  return t;
}

bool split_log_channel(const std::string& src, std::string* log, std::string* channel) {
  const size_t colon = src.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == src.size()) return false;
  std::error_code ec;
  const std::string log_part = src.substr(0, colon);
  // Any file or folder (a bag) that exists: a FIFO or device is split too, so the command can refuse it by name.
  if (!std::filesystem::exists(log_part, ec)) return false;
  std::string channel_part = src.substr(colon + 1);  // before *log is written: log or channel may alias src
  *log = log_part;
  *channel = std::move(channel_part);
  return true;
}

Result<Trajectory> load_trajectory(const std::string& src, TrajectoryFormat format, const std::string& times) {
  if (std::string log, channel; split_log_channel(src, &log, &channel)) return load_log_channel(log, channel);
  if (format == TrajectoryFormat::kAuto) {
    std::string why;
    format = detect(src, why);
    if (format == TrajectoryFormat::kAuto) return Error{why};
  }
  if (!times.empty() && format != TrajectoryFormat::kKitti) {
    return Error{src + ": a times file goes with KITTI poses, and this is a " + to_string(format) + " file"};
  }
  switch (format) {
    case TrajectoryFormat::kTum: return load_tum(src);
    case TrajectoryFormat::kKitti: return load_kitti(src, times);
    case TrajectoryFormat::kEuroc: return load_euroc(src);
    case TrajectoryFormat::kAuto: break;
  }
  return Error{src + ": unknown format"};
}

Status write_tum(const std::string& path, const Trajectory& t) {
  std::string text;
  for (size_t i = 0; i < t.size(); ++i) {
    const auto& p = t.positions[i];
    const auto& q = t.orientations[i];
    appendf(text, "%.6f %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", t.stamps[i], p.x(), p.y(), p.z(), q.x(), q.y(),
            q.z(), q.w());
  }
  return write_file_atomically(path, text);
}

}  // namespace driftlab::analyzers
