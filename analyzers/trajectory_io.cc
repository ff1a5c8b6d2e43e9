#include "analyzers/trajectory_io.h"

#include <sys/stat.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>

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

/// One decimal number. Numbers whose digits form an integer of at most 2^53, with up to 22 decimals, as TUM files hold,
/// take Clinger's fast path (an integer and a power of ten, both exact in a double, so one division rounds
/// correctly); anything else goes to std::from_chars. Both give the correctly rounded double, as numpy does.
const char* parse_double(const char* p, const char* end, double& out) {
  static constexpr double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                                      1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
  const char* q = p;
  const bool negative = q < end && *q == '-';
  if (negative) ++q;
  uint64_t mantissa = 0;
  const char* start = q;
  while (q < end && static_cast<unsigned>(*q - '0') < 10) mantissa = mantissa * 10 + static_cast<unsigned>(*q++ - '0');
  const char* dot = q;
  if (q < end && *q == '.') {
    ++q;
    while (q < end && static_cast<unsigned>(*q - '0') < 10) mantissa = mantissa * 10 + static_cast<unsigned>(*q++ - '0');
  }
  const long decimals = q > dot ? q - dot - 1 : 0;
  const long digits = q - start - (q > dot ? 1 : 0);  // at most 19 digits cannot overflow 64 bits
  const bool plain = digits > 0 && (q == end || *q == ' ' || *q == '\t' || *q == ',' || *q == '\r');
  if (plain && digits <= 19 && mantissa <= (uint64_t{1} << 53) && decimals <= 22) {
    const double v = static_cast<double>(mantissa) / kPow10[decimals];
    out = negative ? -v : v;
    return q;
  }
  const auto [next, ec] = std::from_chars(p, end, out);
  return ec == std::errc() ? next : nullptr;
}

/// Parses the numbers of one line; returns how many it found (at most 9).
int parse_numbers(const char* p, const char* end, double* out) {
  int n = 0;
  while (p < end) {
    while (p < end && (*p == ' ' || *p == '\t' || *p == ',' || *p == '\r')) ++p;
    if (p >= end) break;
    if (n == 9) return n + 1;
    const char* next = parse_double(p, end, out[n]);
    if (next == nullptr || next == p) return -1;
    p = next;
    ++n;
  }
  return n;
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
  const char* p = text.data();
  const char* end = p + text.size();
  for (size_t line = 1; p < end; ++line) {
    const char* eol = static_cast<const char*>(std::memchr(p, '\n', static_cast<size_t>(end - p)));
    if (eol == nullptr) eol = end;
    const char* q = p;
    while (q < eol && (*q == ' ' || *q == '\t' || *q == '\r')) ++q;
    if (q < eol && *q != '#') {
      double v[9];
      const int n = parse_numbers(q, eol, v);
      if (n != 8) {
        return Error{path + ":" + std::to_string(line) +
                     (n < 0 ? ": not a number" : ": expected 8 numbers (t x y z qx qy qz qw), found " + std::to_string(n))};
      }
      for (int i = 0; i < 8; ++i) {
        if (!std::isfinite(v[i])) return Error{path + ":" + std::to_string(line) + ": a number is not finite"};
      }
      const Eigen::Quaterniond quat(v[7], v[4], v[5], v[6]);
      if (quat.norm() < 1e-9) return Error{path + ":" + std::to_string(line) + ": the quaternion is zero"};
      t.push_back(v[0], Eigen::Vector3d(v[1], v[2], v[3]), quat);
    }
    p = eol + 1;
  }
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
