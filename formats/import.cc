#include "formats/import.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <optional>

#include <filesystem>

#include "core/log_writer.h"
#include "core/number_text.h"
#include "core/text_file.h"
#include "formats/carmen.h"
#include "formats/compression.h"
#include "formats/internal/importer.h"
#include "formats/mcap.h"
#include "formats/ros1_bag.h"
#include "formats/ros2_bag.h"
#include "formats/ulog.h"

namespace driftlab::formats {
namespace {

using internal::import_carmen;
using internal::import_mcap;
using internal::import_ros1;
using internal::import_sqlite;
using internal::import_ulog;
using internal::Importer;

/// Up to n bytes from the start of path (fewer for a short file; empty when it cannot be read).
std::string head_of(const std::string& path, size_t n) {
  std::string s(n, '\0');
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) return {};
  const ssize_t got = ::read(fd, s.data(), n);
  ::close(fd);
  s.resize(got > 0 ? static_cast<size_t>(got) : 0);
  return s;
}

/// MRPT's serialization starts every object with 0x80 + the length of its class name, then the name: MRPT 1's
/// "CSensoryFrame", MRPT 2's with its namespace, "mrpt::obs::CObservationOdometry" (what carmen2rawlog writes).
bool looks_like_mrpt(std::string_view h) {
  if (h.size() < 2) return false;
  const auto first = static_cast<unsigned char>(h[0]);
  const size_t len = first & 0x7f;
  if (!(first & 0x80) || len < 2 || len > 100 || h.size() < 1 + len) return false;
  const std::string_view name = h.substr(1, len);
  if (name[0] != 'C' && !name.starts_with("mrpt::")) return false;
  return std::all_of(name.begin(), name.end(),
                     [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == ':'; });
}

std::string describe(std::string_view h) {
  if (h.empty()) return "an empty file";
  const bool text = std::all_of(h.begin(), h.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return u >= 0x20 || c == '\n' || c == '\r' || c == '\t' || u >= 0x80;
  });
  if (text) {
    std::string first(h.substr(0, std::min<size_t>(h.find('\n'), 40)));
    return "text starting \"" + first + "\"";
  }
  static constexpr char kHex[] = "0123456789abcdef";
  std::string bytes;
  for (size_t i = 0; i < std::min<size_t>(h.size(), 8); ++i) {
    const auto u = static_cast<unsigned char>(h[i]);
    bytes += std::string{kHex[u >> 4], kHex[u & 15]} + (i + 1 < std::min<size_t>(h.size(), 8) ? " " : "");
  }
  return "binary data starting " + bytes;
}

/// "b_10.mcap" after "b_2.mcap": runs of digits compare as numbers.
bool natural_less(const std::string& a, const std::string& b) {
  size_t i = 0, j = 0;
  auto digit = [](char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; };
  while (i < a.size() && j < b.size()) {
    if (digit(a[i]) && digit(b[j])) {
      size_t ie = i, je = j;
      while (ie < a.size() && digit(a[ie])) ++ie;
      while (je < b.size() && digit(b[je])) ++je;
      std::string_view da = std::string_view(a).substr(i, ie - i), db = std::string_view(b).substr(j, je - j);
      da.remove_prefix(std::min(da.find_first_not_of('0'), da.size()));
      db.remove_prefix(std::min(db.find_first_not_of('0'), db.size()));
      if (da.size() != db.size()) return da.size() < db.size();
      if (da != db) return da < db;
      i = ie;
      j = je;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i;
      ++j;
    }
  }
  return a.size() - i < b.size() - j;
}

bool is_dir(const std::string& p) {
  std::error_code ec;
  return std::filesystem::is_directory(p, ec);
}
bool exists(const std::string& p) {
  std::error_code ec;
  return std::filesystem::exists(p, ec);
}

/// A bag folder's storage files: from metadata.yaml, else every .mcap and .db3 (compressed or not) in it.
std::vector<std::string> folder_files(const std::string& folder, const Ros2BagMetadata* metadata) {
  std::vector<std::string> files;
  if (metadata) {
    for (const auto& f : metadata->relative_file_paths) {
      // Older rosbag2 versions list the path with the folder's own name in front.
      std::string p = folder + "/" + f;
      const std::string base = folder + "/" + std::filesystem::path(f).filename().string();
      if (!exists(p) && exists(base)) p = base;
      files.push_back(p);
    }
    return files;
  }
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(folder, ec)) {
    const std::string name = e.path().filename().string();
    for (const char* ext : {".mcap", ".db3", ".mcap.zstd", ".db3.zstd"}) {
      if (name.ends_with(ext)) {
        files.push_back(e.path().string());
        break;
      }
    }
  }
  std::sort(files.begin(), files.end(), natural_less);
  return files;
}

/// The MCAP header's profile ("ros2"), from the first bytes.
std::string mcap_profile(std::string_view h) {
  if (h.size() < 8 + 9 + 4 || static_cast<uint8_t>(h[8]) != 0x01) return {};
  uint32_t n;
  std::memcpy(&n, h.data() + 17, 4);
  if (n > h.size() - 21) return {};
  return std::string(h.substr(21, n));
}

Detected detect_head(std::string_view h, bool inner = false);

}  // namespace

namespace {

Detected detect_head(std::string_view h, bool inner) {
  const auto* u = reinterpret_cast<const uint8_t*>(h.data());
  if (Ros1BagReader::looks_like({u, h.size()})) return {Format::kRos1Bag, "ROS 1 bag", {}};
  if (McapReader::looks_like({u, h.size()})) {
    const std::string profile = mcap_profile(h);
    return {Format::kMcap, profile == "ros2" ? "ROS 2 bag (MCAP)" : profile == "ros1" ? "ROS 1 MCAP" : "MCAP file", {}};
  }
  if (SqliteBagReader::looks_like({u, h.size()})) return {Format::kRos2Sqlite, "ROS 2 bag (sqlite3)", {}};
  if (UlogReader::looks_like({u, h.size()})) return {Format::kUlog, "PX4 ULog", {}};
  if (h.size() >= 4 && static_cast<unsigned char>(h[0]) == 0xED && static_cast<unsigned char>(h[1]) == 0xA2 &&
      static_cast<unsigned char>(h[2]) == 0xDA && static_cast<unsigned char>(h[3]) == 0xEA) {
    return {Format::kLcmLog, "LCM log", {}};
  }
  if (!inner && looks_like_zstd({u, h.size()})) {
    // rosbag2's file compression: look at what the frame holds (its first block is enough).
    std::vector<uint8_t> head;
    (void)decompress(Codec::kZstd, {u, h.size()}, 0, head);
    const std::string text(head.begin(), head.begin() + static_cast<ptrdiff_t>(std::min<size_t>(head.size(), 4096)));
    Detected d = detect_head(text, true);
    if (d.format == Format::kMcap || d.format == Format::kRos2Sqlite || d.format == Format::kRos1Bag) {
      return {Format::kZstd, d.name + ", compressed whole with zstd", {}};
    }
    return {Format::kUnknown, "", "zstd data holding " + (text.empty() ? std::string("nothing readable") : describe(text))};
  }
  std::string text(h);
  if (!inner && h.size() >= 2 && static_cast<unsigned char>(h[0]) == 0x1f && static_cast<unsigned char>(h[1]) == 0x8b) {
    // gzip: look at what it holds (a partial inflate of the first block is enough).
    std::vector<uint8_t> inflated;
    (void)decompress(Codec::kGzip, {u, h.size()}, 0, inflated);
    text.assign(inflated.begin(), inflated.begin() + static_cast<ptrdiff_t>(std::min<size_t>(inflated.size(), 4096)));
    if (text.empty()) return {Format::kUnknown, "", "gzip data that does not inflate"};
  }
  if (CarmenReader::looks_like(text)) return {Format::kCarmen, "CARMEN log", {}};
  if (looks_like_mrpt(text)) return {Format::kMrptRawlog, "MRPT rawlog", {}};
  return {Format::kUnknown, "", (text.size() == h.size() ? "" : "gzip holding ") + describe(text)};
}

/// files without the second and later spellings of one file (by device and inode, so "./a.mcap", links and
/// "a.mcap" are one; by path when it cannot be looked at): a file listed twice in metadata.yaml, or given twice on
/// the command line, is read once (it was imported twice, every message doubled). Each left out goes in *twice as
/// "LATER (the same file as FIRST)".
std::vector<std::string> once_each(const std::vector<std::string>& files, std::vector<std::string>* twice) {
  std::vector<std::string> out;
  std::map<std::string, std::string> first_of;  // by device:inode or path, the first spelling
  for (const auto& f : files) {
    struct stat st {};
    std::string id;
    if (::stat(f.c_str(), &st) == 0) {
      id = std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);
    } else {
      id = "path " + std::filesystem::absolute(f).lexically_normal().string();
    }
    auto [it, fresh] = first_of.emplace(id, f);
    if (fresh) {
      out.push_back(f);
    } else if (twice) {
      twice->push_back(f + (f == it->second ? std::string() : " (the same file as " + it->second + ")"));
    }
  }
  return out;
}

constexpr char kKnownFormats[] =
    "ROS 1 bag, ROS 2 bag (MCAP, sqlite3, or its folder), MCAP file, CARMEN log, PX4 ULog, MRPT rawlog";

/// Imports one file (not a folder) into out.
Status import_file(const std::string& path, const std::string& out_path, Importer& out) {
  const Detected d = detect_format(path);
  out.file = path;
  switch (d.format) {
    case Format::kRos1Bag: return import_ros1(path, out);
    case Format::kMcap: return import_mcap(path, out);
    case Format::kRos2Sqlite: return import_sqlite(path, out);
    case Format::kCarmen: return import_carmen(path, out);
    case Format::kUlog: return import_ulog(path, out);
    case Format::kZstd: {
      // Decompressed beside the output (a bag may not fit in memory, nor in a RAM-backed /tmp), then read.
      const std::string plain = out_path + ".unzstd";
      Status s = decompress_zstd_file(path, plain);
      if (!s && !exists(plain)) return s;
      if (!s) out.problem(s.message());
      const Detected inner = detect_format(plain);
      // Problems name the user's file, with offsets into what it decompresses to (they named the temporary file).
      out.temporary = plain;
      out.temporary_named = path + " (decompressed)";
      Status r = inner.format == Format::kMcap        ? import_mcap(plain, out)
                 : inner.format == Format::kRos2Sqlite ? import_sqlite(plain, out)
                 : inner.format == Format::kRos1Bag    ? import_ros1(plain, out)
                                                       : Status(Error(path + ": decompressed, not a bag"));
      std::remove(plain.c_str());
      if (!r) r = Error(out.named(r.message()));
      out.temporary.clear();
      return r;
    }
    case Format::kLcmLog: return Error(path + ": already an LCM log; nothing to import");
    case Format::kMrptRawlog: return Error(path + ": an MRPT rawlog: use `driftlab import rawlog`");
    case Format::kRos2Folder: return Error(path + ": a bag folder among files: give the folder alone");
    case Format::kUnknown: break;
  }
  return Error(path + ": not a format driftlab imports (" + kKnownFormats + "): " + d.description);
}

}  // namespace

Detected detect_format(const std::string& path) {
  if (is_dir(path)) {
    if (exists(path + "/metadata.yaml") || !folder_files(path, nullptr).empty()) {
      return {Format::kRos2Folder, "ROS 2 bag", {}};
    }
    return {Format::kUnknown, "", "a folder without metadata.yaml or bag files"};
  }
  return detect_head(head_of(path, 4096));
}

bool is_importable(Format f) {
  return f != Format::kUnknown && f != Format::kLcmLog && f != Format::kMrptRawlog;
}

std::vector<std::string> recording_files(const std::vector<std::string>& inputs) {
  if (inputs.size() == 1 && is_dir(inputs[0])) {
    auto metadata = read_ros2_metadata(inputs[0]);
    return once_each(folder_files(inputs[0], metadata ? &*metadata : nullptr), nullptr);
  }
  std::vector<std::string> files = once_each(inputs, nullptr);
  std::sort(files.begin(), files.end(), natural_less);
  return files;
}

namespace {
/// A partial output removed unless it was renamed into place (path cleared).
struct RemovedUnlessKept {
  std::string path;
  explicit RemovedUnlessKept(std::string p) : path(std::move(p)) {}
  RemovedUnlessKept(const RemovedUnlessKept&) = delete;
  RemovedUnlessKept& operator=(const RemovedUnlessKept&) = delete;
  ~RemovedUnlessKept() {
    if (!path.empty()) std::remove(path.c_str());
  }
};
}  // namespace

Result<ImportSummary> import_log(const std::string& in, const std::string& out_path,
                                 const std::function<void(const std::string&)>& on_problem) {
  return import_log(std::vector<std::string>{in}, out_path, on_problem);
}

Result<ImportSummary> import_log(const std::vector<std::string>& inputs, const std::string& out_path,
                                 const std::function<void(const std::string&)>& on_problem) {
  if (inputs.empty()) return Error("nothing to import");
  // Everything that can be refused is refused before the output is created.
  const bool folder = inputs.size() == 1 && is_dir(inputs[0]);
  std::optional<Ros2BagMetadata> metadata;
  std::vector<std::string> early_problems;
  std::vector<std::string> files;
  std::string format;
  if (folder) {
    const Detected d = detect_format(inputs[0]);
    if (d.format == Format::kUnknown) return Error(inputs[0] + ": not a ROS 2 bag: " + d.description);
    if (auto m = read_ros2_metadata(inputs[0])) {
      metadata = std::move(*m);
    } else {
      early_problems.push_back(m.error().message + "; reading the bag files in the folder in name order");
    }
    std::vector<std::string> twice;
    files = once_each(folder_files(inputs[0], metadata ? &*metadata : nullptr), &twice);
    for (const auto& f : twice) early_problems.push_back(f + ": listed twice in metadata.yaml; read once");
    if (files.empty()) return Error(inputs[0] + ": metadata.yaml lists no files");
    const std::string storage = metadata ? metadata->storage_identifier : "";
    format = "ROS 2 bag (" + (storage.empty() ? std::string("folder") : storage) + ")";
  } else {
    std::vector<std::string> twice;
    (void)once_each(inputs, &twice);
    for (const auto& f : twice) early_problems.push_back(f + ": given twice; read once");
    files = recording_files(inputs);
    for (const auto& f : files) {
      if (is_dir(f)) return Error(f + ": a bag folder among files: give the folder alone");
      const Detected d = detect_format(f);
      if (!is_importable(d.format) || d.format == Format::kRos2Folder) {
        if (d.format == Format::kLcmLog) return Error(f + ": already an LCM log; nothing to import");
        if (d.format == Format::kMrptRawlog) return Error(f + ": an MRPT rawlog: use `driftlab import rawlog`");
        return Error(f + ": not a format driftlab imports (" + kKnownFormats + "): " + d.description);
      }
      if (format.empty()) format = d.name;
    }
  }
  if (files.size() > 1) format += ", " + std::to_string(files.size()) + " files";

  // Written under a name of its own beside the output, created exclusively, and renamed into place when whole: two
  // processes converting one recording into one cache at once each write their own file (they shared
  // OUT.partial, and one renamed the other's half-written log into place).
  auto own = create_partial_of_its_own(out_path);
  if (!own) return own.error();
  ::close(own->fd);
  RemovedUnlessKept partial{own->path};
  // The kernel's copy into the file on a thread of its own, overlapping the conversion.
  auto writer = LogWriter::create(partial.path, {.background = true});
  if (!writer) return writer.error();
  Importer out(std::move(*writer), on_problem);
  out.summary.format = format;
  for (const auto& p : early_problems) out.problem(p);
  for (const auto& f : files) {
    if (folder && !exists(f)) {
      out.problem(f + ": listed in metadata.yaml, missing");
      continue;
    }
    Status s = import_file(f, partial.path, out);  // its temporary files named after the partial file: its own too
    if (!s && out.status()) {
      // A file that cannot be read at all: fatal alone, a problem among several (the others still convert).
      if (files.size() == 1) {
        out.writer().discard();
        return s.error();
      }
      out.problem(s.message());
    }
    if (!out.status()) {
      out.writer().discard();
      return out.status().error();
    }
  }
  // Every message accounted for: what metadata.yaml counts per topic against what the files held.
  if (metadata) {
    for (const auto& t : metadata->topics) {
      int64_t found = 0;
      for (const auto& c : out.summary.topics)
        if (c.channel == t.name) found = c.messages + c.malformed;
      if (found < t.message_count) {
        out.problem(inputs[0] + "/metadata.yaml: counts " + std::to_string(t.message_count) + " messages on " +
                    t.name + "; the files hold " + std::to_string(found));
      }
    }
  }
  if (Status c = out.writer().close(); !c) return c.error();
  if (std::rename(partial.path.c_str(), out_path.c_str()) != 0) {
    return Error(out_path + ": cannot rename " + partial.path + " into place: " + std::strerror(errno),
                 ErrorCode::kCannotWrite);
  }
  partial.path.clear();  // in place: nothing to remove
  return out.summary;
}

std::string import_text(const ImportSummary& s, const std::string& from, const std::string& to) {
  std::string out;
  appendf(out, "%s (%s) -> %s: %s messages\n", from.c_str(), s.format.c_str(), to.c_str(),
          thousands(s.messages).c_str());
  size_t width = 8;
  for (const auto& t : s.topics) width = std::max(width, t.channel.size());
  for (const auto& t : s.topics) {
    appendf(out, "  %-*s %-34s -> %-28s %10s", static_cast<int>(width), t.channel.c_str(), t.source_type.c_str(),
            t.driftlab_type.c_str(), thousands(t.messages).c_str());
    if (t.malformed) appendf(out, "  (%s malformed, left out)", thousands(t.malformed).c_str());
    if (t.driftlab_type == "driftlab.foreign_message_t") out += "  (no mapping: carried as recorded)";
    if (t.driftlab_type == "driftlab.stamped_foreign_message_t")
      out += "  (no mapping: carried as recorded, its header read)";
    out += "\n";
  }
  for (const auto& [name, n] : s.skipped) {
    appendf(out, "  skipped %-20s %s lines (no driftlab type)\n", name.c_str(), thousands(n).c_str());
  }
  return out;
}

}  // namespace driftlab::formats
