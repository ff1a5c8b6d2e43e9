// CARMEN's log format, as carmen/src/logger writes it (and as the Radish and Freiburg datasets use it):
//   ODOM x y theta tv rv accel                                                    ipc_timestamp host logger_timestamp
//   FLASER n r1..rn x y theta odom_x odom_y odom_theta                             (same three)
//   RLASER (as FLASER, the rear laser)
//   RAWLASERk type start_angle fov resolution max_range accuracy remission_mode n r1..rn m e1..em      (same three)
//   ROBOTLASERk (as RAWLASERk) laser_x laser_y laser_theta robot_x robot_y robot_theta tv rv
//               forward_safety side_safety turn_axis                                                  (same three)
//   TRUEPOS x y theta odom_x odom_y odom_theta                                     (same three)
//   PARAM name value [host timestamp]
// Metres and radians; FLASER/RLASER angles are implied: n beams over 180 degrees starting at -90 (180 beams:
// -90..+89, 1 degree apart; 181: -90..+90), unless PARAM laser_*_resolution / laser_*_fov say otherwise. The
// laser's longest possible reading means "no return".
#include "formats/carmen.h"

#include <zlib.h>
#include <algorithm>
#include <array>

#include <charconv>
#include <climits>
#include <cmath>
#include <map>
#include <numbers>
#include <optional>

#include "core/mapped_file.h"
#include "core/time.h"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "formats/compression.h"
#include "lcmtypes/encode.h"
#include "lcmtypes/planar.h"

namespace driftlab::formats {
namespace {

using lcmtypes::encode;

using Tokens = std::vector<std::string_view>;

constexpr size_t kHeadBytes = 64 << 10;     // what open() looks at
constexpr size_t kMaxLineBytes = 16 << 20;  // a gzip log's longest line (CARMEN's are a few KB)

void split(std::string_view line, Tokens& out) {
  out.clear();
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    const size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
}

std::optional<double> number(std::string_view s) {
  double v = 0;
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc{} || p != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

/// The problem with a count (of readings, of remissions) larger than the numbers on its line: it cannot be met,
/// and one beyond size_t's range was undefined to convert (UBSan, the import fuzzer: "FLASER 1.7e47 ...").
std::string more_than_given(double count, const char* what, size_t numbers) {
  char text[32];
  const auto end = std::to_chars(text, text + sizeof text, count).ptr;
  return std::string(text, end) + " " + what + " announced, " + std::to_string(numbers) + " numbers on the line";
}

/// The largest magnitude of a time in seconds that whole microseconds in int64_t hold.
constexpr double kMaxSeconds = 9.2e12;

int64_t to_utime(double s) { return Time::from_seconds_rounded(s).us(); }

/// The laser number K of RAWLASERK or ROBOTLASERK (digits only); empty for any other name.
std::string_view laser_number(std::string_view name) {
  for (const std::string_view word : {"RAWLASER", "ROBOTLASER"}) {
    if (!name.starts_with(word) || name.size() == word.size()) continue;
    const std::string_view k = name.substr(word.size());
    return std::all_of(k.begin(), k.end(), [](char c) { return c >= '0' && c <= '9'; }) ? k : std::string_view();
  }
  return {};
}

/// FLASER, RLASER, RAWLASERK and ROBOTLASERK. A name with anything but digits after the word (the fuzzer's
/// "RAWLASER" and four NULs) is no laser: its frame would have carried the NULs into a message that does not hold
/// its type's layout.
bool is_laser(std::string_view name) { return name == "FLASER" || name == "RLASER" || !laser_number(name).empty(); }

/// The TF frame of a laser: the front one (FLASER, RAWLASER1, ROBOTLASER1) is "laser", the rear one
/// (RLASER, RAWLASER2, ROBOTLASER2) "rear_laser", others "laserK".
std::string laser_frame(std::string_view name) {
  if (name == "FLASER") return "laser";
  if (name == "RLASER") return "rear_laser";
  const std::string_view k = laser_number(name);
  return k == "1" ? "laser" : k == "2" ? "rear_laser" : "laser" + std::string(k);
}

/// The pose of a laser line's laser in its robot's frame (x, y, yaw), from the two poses the line carries: FLASER
/// and RLASER give the laser's and then the robot's after their readings, ROBOTLASERk after its remissions
/// (CARMEN's readlog.c reads them so). Empty when the line is too short or a pose is not a finite number (the second
/// pass says what is wrong).
std::optional<std::array<double, 3>> mounting_on_line(const Tokens& t) {
  auto count = [&](size_t i) -> std::optional<size_t> {
    auto x = i < t.size() ? number(t[i]) : std::nullopt;
    if (!x || *x < 0 || *x != std::floor(*x) || *x >= static_cast<double>(t.size())) return std::nullopt;
    return static_cast<size_t>(*x);
  };
  std::optional<size_t> at;  // the laser pose's first token
  if (t[0] == "FLASER" || t[0] == "RLASER") {
    if (const auto n = count(1)) at = 2 + *n;
  } else {
    const auto n = count(8);  // after the name: type start fov resolution max_range accuracy remission_mode n
    const auto m = n ? count(9 + *n) : std::nullopt;
    if (m) at = 10 + *n + *m;
  }
  if (!at) return std::nullopt;
  std::array<double, 6> pose{};  // laser x y theta, robot x y theta
  for (size_t i = 0; i < pose.size(); ++i) {
    auto x = *at + i < t.size() ? number(t[*at + i]) : std::nullopt;
    if (!x || !std::isfinite(*x)) return std::nullopt;
    pose[i] = *x;
  }
  const double dx = pose[0] - pose[3], dy = pose[1] - pose[4], c = std::cos(pose[5]), s = std::sin(pose[5]);
  return std::array<double, 3>{c * dx + s * dy, -s * dx + c * dy,
                               std::remainder(pose[2] - pose[5], 2 * std::numbers::pi)};
}

/// A laser's mounting as its lines say it: the same on every line (to 1 mm and 0.001 rad, what their six decimals
/// and a turn's rounding leave) is a mounting (the Freiburg clinic's ROBOTLASER1 lines: the laser 0.22 m ahead);
/// one that varies is not (a corrected log's first pose is the corrected one, its second the odometry's).
struct LineMounting {
  std::array<double, 3> first{};
  bool seen = false, constant = true;
  void add(const std::array<double, 3>& m) {
    if (!seen) {
      first = m, seen = true;
    } else if (std::hypot(m[0] - first[0], m[1] - first[1]) > 1e-3 ||
               std::abs(std::remainder(m[2] - first[2], 2 * std::numbers::pi)) > 1e-3) {
      constant = false;
    }
  }
};

/// What a pass over the log learns before converting: the PARAM values; for FLASER/RLASER (which do not carry
/// their maximum range), the largest reading and how often it occurs; for each laser, its mounting as its lines say
/// it.
struct Preamble {
  std::map<std::string, double, std::less<>> params;
  std::map<std::string, LineMounting, std::less<>> mounting;               // by laser frame
  std::map<std::string, std::pair<double, int64_t>, std::less<>> longest;  // laser -> (reading, count)
  std::map<std::string, int64_t, std::less<>> readings;                   // laser -> readings seen

  std::optional<double> param(std::string_view name) const {
    auto it = params.find(name);
    return it == params.end() ? std::nullopt : std::optional<double>(it->second);
  }
  /// The reading that means "no return" for FLASER/RLASER: PARAM robot_{front,rear}_laser_max, else the longest
  /// reading when the laser clamps to it (a SICK reports its maximum, 81.83 m or 50 m, for every beam without a
  /// return: at least 0.1% of the readings, where a real hit at the far limit is a handful).
  std::optional<double> no_return(std::string_view laser) const {
    if (auto p = param(laser == "RLASER" ? "robot_rear_laser_max" : "robot_front_laser_max")) return *p;
    auto it = longest.find(laser);
    if (it == longest.end()) return std::nullopt;
    const int64_t total = readings.find(laser)->second;
    return it->second.second * 1000 >= total ? std::optional<double>(it->second.first) : std::nullopt;
  }
};

}  // namespace

bool CarmenReader::looks_like(std::string_view head) {
  static constexpr std::string_view kWords[] = {"PARAM", "ODOM", "FLASER", "RLASER", "RAWLASER", "ROBOTLASER",
                                                "TRUEPOS", "SYNC", "NEFF", "GPSNMEA", "SONAR", "BUMPER"};
  Tokens t;
  int known = 0;
  size_t pos = 0;
  for (int lines = 0; lines < 20 && pos < head.size(); ++lines) {
    size_t eol = head.find('\n', pos);
    if (eol == std::string_view::npos) eol = head.size();
    std::string_view line = head.substr(pos, eol - pos);
    pos = eol + 1;
    if (line.empty() || line[0] == '#') continue;
    split(line, t);
    if (t.empty()) continue;
    const bool word = std::any_of(std::begin(kWords), std::end(kWords),
                                  [&](std::string_view w) { return t[0].starts_with(w); });
    if (!word) return false;
    ++known;
  }
  return known > 0;
}

Result<CarmenReader> CarmenReader::open(const std::string& path) {
  auto file = MappedFile::open(path);
  if (!file) return file.error();
  auto bytes = file->bytes();
  CarmenReader r;
  std::string head;
  if (bytes.size() >= 2 && bytes[0] == 0x1f && bytes[1] == 0x8b) {
    // Only the head is inflated here; the log is inflated as it is read (a 10 MB .clf.gz can hold 10 GB).
    std::vector<uint8_t> out;
    const std::string error = decompress(Codec::kGzip, bytes, 0, out, kHeadBytes);
    if (out.empty() && !error.empty()) return Error(path + ": " + error + " after 0 bytes");
    head.assign(out.begin(), out.end());
    r.gzip_ = true;
  } else {
    head.assign(bytes.begin(), bytes.begin() + static_cast<ptrdiff_t>(std::min<size_t>(bytes.size(), kHeadBytes)));
  }
  if (!looks_like(head)) return Error(path + ": not a CARMEN log (its first lines are not CARMEN messages)");
  r.file_ = std::move(*file);
  return r;
}

std::string CarmenReader::each_line(const std::function<void(size_t, std::string_view)>& fn, size_t* stopped_at) const {
  size_t line = 0;
  *stopped_at = 0;
  if (!gzip_) {
    const std::string_view text =
        file_.bytes().empty()
            ? std::string_view(text_)
            : std::string_view(reinterpret_cast<const char*>(file_.bytes().data()), file_.bytes().size());
    size_t pos = 0;
    while (pos < text.size()) {
      size_t eol = text.find('\n', pos);
      if (eol == std::string_view::npos) eol = text.size();
      fn(++line, text.substr(pos, eol - pos));
      pos = eol + 1;
    }
    return {};
  }
  const auto in = file_.bytes();
  z_stream s{};
  if (inflateInit2(&s, 15 + 32) != Z_OK) return "gzip: cannot start the decoder";
  const uint64_t budget = DecodeBudget(in.size()).total();
  std::vector<char> buf(size_t{1} << 20);
  std::string pending;  // a line begun in an earlier buffer
  size_t pos = 0;
  uint64_t total = 0;
  std::string error;
  for (;;) {
    const size_t feed = std::min<size_t>(in.size() - pos, UINT_MAX);
    s.next_in = const_cast<Bytef*>(in.data() + pos);
    s.avail_in = static_cast<uInt>(feed);
    s.next_out = reinterpret_cast<Bytef*>(buf.data());
    s.avail_out = static_cast<uInt>(buf.size());
    const int rc = inflate(&s, Z_NO_FLUSH);
    const size_t got = buf.size() - s.avail_out;
    pos += feed - s.avail_in;
    total += got;
    const std::string_view chunk(buf.data(), got);
    for (size_t p = 0;;) {
      const size_t eol = chunk.find('\n', p);
      if (eol == std::string_view::npos) {
        pending.append(chunk.substr(p));
        break;
      }
      if (pending.empty()) {
        fn(++line, chunk.substr(p, eol - p));
      } else {
        pending.append(chunk.substr(p, eol - p));
        fn(++line, pending);
        pending.clear();
      }
      p = eol + 1;
    }
    if (pending.size() > kMaxLineBytes) {
      error = "a line longer than " + std::to_string(kMaxLineBytes) + " bytes (at byte " + std::to_string(pos) +
              " of the gzip file): the rest of the log is not read (a decompression bomb or not a CARMEN log)";
      pending.clear();
      break;
    }
    if (total > budget) {
      error = "inflates to more than " + std::to_string(budget) + " bytes (" +
              std::to_string(DecodeBudget::kTotalRatio) + " times its size and " +
              std::to_string(DecodeBudget::kFreeTotalBytes) + "; at byte " + std::to_string(pos) +
              " of the gzip file): the rest is not read (a decompression bomb)";
      pending.clear();
      break;
    }
    if (rc == Z_STREAM_END) {
      // Concatenated gzip members (what `cat a.gz b.gz` makes) go on.
      if (pos < in.size() && inflateReset(&s) == Z_OK) continue;
      break;
    }
    if (rc != Z_OK && rc != Z_BUF_ERROR) {
      error = std::string("gzip: ") + (s.msg ? s.msg : "corrupt data") + " at byte " + std::to_string(pos) +
              "; the rest is lost";
      break;
    }
    if (pos == in.size() && s.avail_out != 0) {
      error = "gzip: the file ends early (at byte " + std::to_string(pos) + ")";
      break;
    }
  }
  inflateEnd(&s);
  if (!pending.empty()) fn(++line, pending);
  *stopped_at = line + 1;
  return error;
}

int64_t CarmenReader::read(const std::function<void(const CarmenMessage&)>& on_message,
                           const std::function<void(size_t, const std::string&)>& on_problem) {
  // Twice over the lines (the preamble, then the messages); a gzip log's damage is said on the second pass.
  int pass = 0;
  auto for_lines = [&](auto&& fn) {
    Tokens t;
    size_t stopped_at = 0;
    const std::string error = each_line(
        [&](size_t line, std::string_view text) {
          split(text, t);
          if (!t.empty()) fn(line, t);
        },
        &stopped_at);
    if (++pass == 2 && !error.empty()) on_problem(stopped_at, error);
  };

  Preamble pre;
  for_lines([&](size_t, const Tokens& t) {
    if (t[0] == "PARAM" && t.size() >= 3) {
      if (auto v = number(t[2])) pre.params[std::string(t[1])] = *v;
    }
    if (t[0] == "FLASER" || t[0] == "RLASER" || (t[0].starts_with("ROBOTLASER") && !laser_number(t[0]).empty())) {
      if (auto mount = mounting_on_line(t)) pre.mounting[laser_frame(t[0])].add(*mount);
    }
    if ((t[0] == "FLASER" || t[0] == "RLASER") && t.size() > 2) {
      auto n = number(t[1]);
      if (!n || *n < 0 || *n + 2 > static_cast<double>(t.size())) return;
      auto& [longest, count] = pre.longest[std::string(t[0])];
      pre.readings[std::string(t[0])] += static_cast<int64_t>(*n);
      for (size_t i = 0; i < static_cast<size_t>(*n); ++i) {
        const double v = number(t[2 + i]).value_or(0);
        if (v > longest) longest = v, count = 0;
        if (v == longest) ++count;
      }
    }
  });

  std::map<std::string, int64_t, std::less<>> seq;
  std::map<std::string, int64_t, std::less<>> skipped;
  std::vector<double> v;
  int64_t messages = 0;
  bool tf_written = false;

  auto emit = [&](size_t line, std::string_view channel, const char* type, int64_t log_utime, auto&& msg) {
    msg.header.seq = seq[std::string(channel)]++;
    CarmenMessage m{channel, type, log_utime, encode(msg), line};
    on_message(m);
    ++messages;
  };
  auto write_tf = [&](size_t line, int64_t stamp, int64_t log_utime) {
    tf_t tf{};
    tf.header.utime = stamp;
    tf.header.frame_id = "base_link";
    // A laser's mounting: PARAM robot_{front,rear}laser_offset (CARMEN's robot module, straight ahead or behind),
    // else what its lines say when they all say the same (LineMounting), else on the robot's centre.
    std::map<std::string, std::array<double, 3>, std::less<>> mounts;
    for (const auto& [frame, lines] : pre.mounting) {
      if (lines.constant) mounts[frame] = lines.first;
    }
    for (const auto& [frame, param, yaw] : {std::tuple{"laser", "robot_frontlaser_offset", 0.0},
                                            std::tuple{"rear_laser", "robot_rearlaser_offset", std::numbers::pi}}) {
      if (auto offset = pre.param(param)) {
        mounts[frame] = {*offset, 0, yaw};
      } else if (!mounts.contains(frame)) {
        mounts[frame] = {0, 0, yaw};
      }
    }
    for (const auto& [frame, mount] : mounts) {
      transform_t x{};
      x.header.utime = stamp;
      x.header.frame_id = "base_link";
      x.child_frame_id = frame;
      x.translation = {mount[0], mount[1], 0};
      x.rotation = yaw_quaternion(mount[2]);
      tf.transforms.push_back(x);
    }
    tf.ntransforms = static_cast<int32_t>(tf.transforms.size());
    emit(line, "TF_STATIC", "driftlab.tf_t", log_utime, tf);
  };

  for_lines([&](size_t line, const Tokens& t) {
    const std::string_view name = t[0];
    if (name[0] == '#' || name == "PARAM") return;
    const bool known = name == "ODOM" || name == "TRUEPOS" || is_laser(name);
    if (!known) {
      ++skipped[std::string(name)];
      return;
    }
    // The trailer: "ipc_timestamp host logger_timestamp" (older logs: only the timestamp).
    auto bad = [&](const std::string& what) { on_problem(line, std::string(name) + ": " + what); };
    v.clear();
    size_t body_end = t.size();
    std::optional<double> ipc, logger;
    if (t.size() >= 4 && number(t[t.size() - 1]) && !number(t[t.size() - 2]) && number(t[t.size() - 3])) {
      ipc = number(t[t.size() - 3]);
      logger = number(t[t.size() - 1]);
      body_end = t.size() - 3;
    } else if (t.size() >= 2 && number(t.back())) {
      ipc = logger = number(t.back());
      body_end = t.size() - 1;
    }
    if (!ipc) return bad("no timestamp at the end of the line");
    for (size_t i = 1; i < body_end; ++i) {
      auto x = number(t[i]);
      if (!x) return bad("\"" + std::string(t[i].substr(0, 20)) + "\" is not a number");
      v.push_back(*x);
    }
    // A time beyond int64_t microseconds (about 292,000 years either side of 1970) cannot be a log time: llround
    // of 1e300 s gave INT64_MIN, silently.
    for (const double s : {*ipc, *logger}) {
      if (std::fabs(s) >= kMaxSeconds) {
        char text[32];
        const auto end = std::to_chars(text, text + sizeof text, s).ptr;
        return bad("time " + std::string(text, end) + " s is beyond what a log time can hold (+/-9.2e12 s)");
      }
    }
    const int64_t stamp = to_utime(*ipc);
    const int64_t arrival = to_utime(*logger);

    if (name == "ODOM") {
      if (v.size() < 5) return bad("expected x y theta tv rv accel, got " + std::to_string(v.size()) + " numbers");
      odometry_t o{};
      o.header.utime = stamp;
      o.header.frame_id = "odom";
      o.child_frame_id = "base_link";
      o.position = {v[0], v[1], 0};
      o.orientation = yaw_quaternion(v[2]);
      o.linear_velocity = {v[3], 0, 0};
      o.angular_velocity = {0, 0, v[4]};
      return emit(line, "ODOM", "driftlab.odometry_t", arrival, o);
    }
    if (name == "TRUEPOS") {
      if (v.size() < 3) return bad("expected x y theta, got " + std::to_string(v.size()) + " numbers");
      pose_t p{};
      p.header.utime = stamp;
      p.header.frame_id = "world";
      p.child_frame_id = "base_link";
      p.position = {v[0], v[1], 0};
      p.orientation = yaw_quaternion(v[2]);
      return emit(line, "TRUEPOS", "driftlab.pose_t", arrival, p);
    }

    // Lasers.
    laser_scan_t s{};
    s.header.utime = stamp;
    s.header.frame_id = laser_frame(name);
    size_t at = 0;
    double max_reading = std::numeric_limits<double>::infinity();
    std::optional<double> no_return;
    const bool flaser = name == "FLASER" || name == "RLASER";
    if (flaser) {
      if (v.empty() || v[0] < 0 || v[0] != std::floor(v[0])) return bad("no reading count");
      if (v[0] >= static_cast<double>(v.size())) return bad(more_than_given(v[0], "readings", v.size()));
      const auto n = static_cast<size_t>(v[0]);
      if (v.size() != 1 + n + 6) {
        return bad(std::to_string(n) + " readings and a pose need " + std::to_string(n + 7) + " numbers, got " +
                   std::to_string(v.size()));
      }
      const bool front = name == "FLASER";
      const double fov =
          pre.param(front ? "laser_front_laser_fov" : "laser_rear_laser_fov").value_or(180.0) * std::numbers::pi / 180;
      auto res_deg = pre.param(front ? "laser_front_laser_resolution" : "laser_rear_laser_resolution");
      // n beams over the field of view: an odd count includes both ends (181: -90..+90), an even one starts at
      // the right end and stops one step short of the left (180: -90..+89).
      const double res = res_deg ? *res_deg * std::numbers::pi / 180
                                 : fov / static_cast<double>(n % 2 == 1 ? std::max<size_t>(n - 1, 1) : n);
      s.angle_min = static_cast<float>(-fov / 2);
      s.angle_increment = static_cast<float>(res);
      s.angle_max = static_cast<float>(-fov / 2 + res * static_cast<double>(n == 0 ? 0 : n - 1));
      s.nranges = static_cast<int32_t>(n);
      at = 1;
      no_return = pre.no_return(name);
    } else {
      // RAWLASER/ROBOTLASER: type start fov resolution max_range accuracy remission_mode n ... m ...
      if (v.size() < 8 || v[7] < 0 || v[7] != std::floor(v[7])) return bad("no reading count");
      if (v[7] >= static_cast<double>(v.size())) return bad(more_than_given(v[7], "readings", v.size()));
      const auto n = static_cast<size_t>(v[7]);
      if (v.size() < 8 + n + 1) return bad(std::to_string(n) + " readings announced, fewer given");
      const double m = v[8 + n];
      if (m < 0 || m != std::floor(m)) return bad("no remission count");
      if (m >= static_cast<double>(v.size())) return bad(more_than_given(m, "remissions", v.size()));
      const size_t need = 9 + n + static_cast<size_t>(m) + (name.starts_with("ROBOTLASER") ? 11 : 0);
      if (v.size() != need) {
        return bad("expected " + std::to_string(need) + " numbers, got " + std::to_string(v.size()));
      }
      s.angle_min = static_cast<float>(v[1]);
      s.angle_increment = static_cast<float>(v[3]);
      s.angle_max = static_cast<float>(v[1] + v[3] * static_cast<double>(n == 0 ? 0 : n - 1));
      s.nranges = static_cast<int32_t>(n);
      no_return = v[4];
      if (static_cast<size_t>(m) == n) {
        s.intensities.assign(v.begin() + 9 + static_cast<ptrdiff_t>(n), v.begin() + 9 + 2 * static_cast<ptrdiff_t>(n));
        s.nintensities = static_cast<int32_t>(n);
      }
      at = 8;
    }
    s.ranges.assign(v.begin() + static_cast<ptrdiff_t>(at), v.begin() + static_cast<ptrdiff_t>(at) + s.nranges);
    if (no_return) max_reading = *no_return;
    s.range_min = 0;
    // Readings at the maximum mean "no return": range_max sits just below it, so they fall outside.
    s.range_max = std::isfinite(max_reading) ? std::nextafter(static_cast<float>(max_reading), 0.0F)
                                             : std::numeric_limits<float>::max();
    if (!tf_written) {
      write_tf(line, stamp, arrival);
      tf_written = true;
    }
    emit(line, name, "driftlab.laser_scan_t", arrival, s);

    // The pose the line carries (FLASER: x y theta after the readings; ROBOTLASER: the laser pose): in raw logs
    // the odometry's, in corrected logs (GMapping's output) the corrected one.
    const size_t pose_at = flaser ? 1 + static_cast<size_t>(s.nranges)
                                  : name.starts_with("ROBOTLASER") ? v.size() - 11 : v.size();
    if (pose_at + 3 <= v.size()) {
      pose_t p{};
      p.header.utime = stamp;
      p.header.frame_id = "world";
      p.child_frame_id = s.header.frame_id;
      p.position = {v[pose_at], v[pose_at + 1], 0};
      p.orientation = yaw_quaternion(v[pose_at + 2]);
      static thread_local std::string pose_channel;
      pose_channel = std::string(name) + "_POSE";
      emit(line, pose_channel, "driftlab.pose_t", arrival, p);
    }
  });
  skipped_.assign(skipped.begin(), skipped.end());
  return messages;
}

}  // namespace driftlab::formats
