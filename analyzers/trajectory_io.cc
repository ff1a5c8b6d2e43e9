#include "analyzers/trajectory_io.h"

#include <sys/stat.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "analyzers/internal/number_lines.h"
#include "core/log_format.h"
#include "core/log_index.h"
#include "core/log_reader.h"
#include "core/mapped_file.h"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "lcmtypes/validate.h"

namespace driftlab::analyzers {
namespace {

bool is_file(const std::string& path) {
  struct stat st {};
  return stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

}  // namespace

Result<Trajectory> load_tum(const std::string& path) {
  auto mapped = MappedFile::open(path);
  if (!mapped) return mapped.error();
  const auto bytes = mapped->bytes();
  const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  Trajectory t;
  // About 60 bytes a line: reserve once rather than grow.
  const size_t expected = text.size() / 48 + 16;
  t.stamps.reserve(expected);
  t.positions.reserve(expected);
  t.orientations.reserve(expected);
  std::string error;
  internal::for_each_data_line(text, [&](size_t line, const char* p, const char* eol) {
    double v[8];
    const int n = internal::parse_numbers(p, eol, v, 8);
    if (n != 8) {
      error = path + ":" + std::to_string(line) +
              (n < 0 ? ": not a number" : ": expected 8 numbers (t x y z qx qy qz qw), found " + std::to_string(n));
      return false;
    }
    for (int i = 0; i < 8; ++i) {
      if (!std::isfinite(v[i])) {
        error = path + ":" + std::to_string(line) + ": a number is not finite";
        return false;
      }
    }
    const Eigen::Quaterniond quat(v[7], v[4], v[5], v[6]);
    if (quat.norm() < 1e-9) {
      error = path + ":" + std::to_string(line) + ": the quaternion is zero";
      return false;
    }
    t.push_back(v[0], Eigen::Vector3d(v[1], v[2], v[3]), quat);
    return true;
  });
  if (!error.empty()) return Error{error};
  if (t.size() == 0) return Error{path + ": no poses (expected lines of \"t x y z qx qy qz qw\")"};
  return t;
}

bool append_pose(std::span<const uint8_t> data, Trajectory& t) {
  const int64_t fp = logfmt::fingerprint(data);
  auto add = [&](const auto& m) {
    t.push_back(static_cast<double>(m.header.utime) * 1e-6, {m.position.x, m.position.y, m.position.z},
                {m.orientation.w, m.orientation.x, m.orientation.y, m.orientation.z});
    return true;
  };
  if (fp == driftlab::pose_t::getHash()) {
    driftlab::pose_t pose;
    return lcmtypes::decode(data, pose) && add(pose);
  }
  if (fp == driftlab::odometry_t::getHash()) {
    driftlab::odometry_t odom;
    return lcmtypes::decode(data, odom) && add(odom);
  }
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
    if (fp != driftlab::pose_t::getHash() && fp != driftlab::odometry_t::getHash()) {
      return Error{log + ": channel " + channel + " carries neither driftlab.pose_t nor driftlab.odometry_t (event at byte " +
                   std::to_string(e.offset) + ")"};
    }
    if (!append_pose(e.data, t)) {
      return Error{log + ": event at byte " + std::to_string(e.offset) + " on " + channel + " does not decode as " +
                   (fp == driftlab::pose_t::getHash() ? "driftlab.pose_t" : "driftlab.odometry_t")};
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

Result<Trajectory> load_trajectory(const std::string& src) {
  const size_t colon = src.rfind(':');
  if (colon != std::string::npos && colon > 0 && colon + 1 < src.size() && is_file(src.substr(0, colon))) {
    return load_log_channel(src.substr(0, colon), src.substr(colon + 1));
  }
  return load_tum(src);
}

Status write_tum(const std::string& path, const Trajectory& t) {
  FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) return Error{path + ": cannot create: " + std::strerror(errno)};
  for (size_t i = 0; i < t.size(); ++i) {
    const auto& p = t.positions[i];
    const auto& q = t.orientations[i];
    std::fprintf(f, "%.6f %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", t.stamps[i], p.x(), p.y(), p.z(), q.x(), q.y(), q.z(),
                 q.w());
  }
  if (std::fclose(f) != 0) return Error{path + ": write failed: " + std::strerror(errno)};
  return {};
}

}  // namespace driftlab::analyzers
