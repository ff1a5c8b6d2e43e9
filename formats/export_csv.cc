#include "formats/export_csv.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <set>

#include "core/log_format.h"
#include "core/log_reader.h"
#include "core/number_text.h"
#include "core/time.h"
#include "lcmtypes/schema.h"
#include "lcmtypes/type_registry.h"
#include "lcmtypes/validate.h"

namespace driftlab::formats {
namespace {

namespace fs = std::filesystem;

/// FNV-1a of a channel's whole name, as 16 hex digits.
std::string name_hash(std::string_view channel) {
  uint64_t h = 1469598103934665603ull;
  for (const char c : channel) h = (h ^ static_cast<unsigned char>(c)) * 1099511628211ull;
  char buf[20];
  std::snprintf(buf, sizeof(buf), "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

/// channel_file_name, unless another channel took it already: then "NAME~HASH". Adds the name to *taken.
std::string unique_channel_file_name(std::string_view channel, std::set<std::string>* taken) {
  auto key = [](std::string name) {  // case-insensitive file systems (macOS, Windows) fold "Odom" onto "odom"
    for (auto& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return name;
  };
  std::string name = channel_file_name(channel);
  if (taken->count(key(name))) {
    const std::string base = name.substr(0, std::min<size_t>(name.size(), 200 - 17));
    name = base + "~" + name_hash(channel);
    for (int n = 2; taken->count(key(name)); ++n) name = base + "~" + name_hash(channel) + "-" + std::to_string(n);
  }
  taken->insert(key(name));
  return name;
}

std::string csv_quote(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

/// One channel's CSV, written as OUT/CHANNEL.csv.partial and renamed when the log has been read. Its columns are
/// the union of its messages' fields, in the order they first appear: a later message with more elements (a
/// second transform, a longer scan) adds columns, and the rows before it are given empty cells for them when the
/// file is finished (rewritten once, only then).
struct CsvFile {
  FILE* f = nullptr;
  std::string path;
  std::map<std::string, size_t> column;  // name -> index
  std::vector<std::string> names;        // by index
  size_t header_columns = 0;             // columns in the header written first
  std::vector<std::string> row;
  int64_t rows = 0;
  uint64_t last_use = 0;  // when a row was last written, for closing the file unused longest
};

void write_header(FILE* f, const std::vector<std::string>& names) {
  std::fprintf(f, "log_time_s");
  for (const auto& n : names) std::fprintf(f, ",%s", csv_quote(n).c_str());
  std::fprintf(f, "\n");
}

/// Rewrites a finished file whose columns grew after its header: the whole header, and every row padded with
/// empty cells to its width (a row's cells are never more than the columns known when it was written).
Status widen(const CsvFile& f) {
  const std::string from = f.path + ".partial", to = f.path + ".partial2";
  FILE* in = std::fopen(from.c_str(), "r");
  if (in == nullptr) return Error{from + ": cannot read back: " + std::strerror(errno), ErrorCode::kCannotWrite};
  FILE* out = std::fopen(to.c_str(), "w");
  if (out == nullptr) {
    std::fclose(in);
    return Error{to + ": cannot create: " + std::strerror(errno), ErrorCode::kCannotWrite};
  }
  write_header(out, f.names);
  const size_t width = f.names.size() + 1;
  bool header = true, quoted = false;
  size_t cells = 1;
  for (int c; (c = std::fgetc(in)) != EOF;) {
    if (c == '"') quoted = !quoted;  // "" inside a quoted cell toggles twice
    if (!quoted && c == ',') ++cells;
    if (!quoted && c == '\n') {
      if (!header) {
        for (; cells < width; ++cells) std::fputc(',', out);
        std::fputc('\n', out);
      }
      header = false;
      cells = 1;
      continue;
    }
    if (!header) std::fputc(c, out);
  }
  const bool read_ok = !std::ferror(in);
  std::fclose(in);
  if (std::fclose(out) != 0 || !read_ok) {
    std::remove(to.c_str());
    return Error{to + ": write failed (disk full?)", ErrorCode::kCannotWrite};
  }
  std::error_code ec;
  fs::rename(to, from, ec);
  if (ec) return Error{from + ": cannot replace: " + ec.message(), ErrorCode::kCannotWrite};
  return {};
}

}  // namespace

std::string channel_file_name(std::string_view channel) {
  size_t from = 0;
  while (from < channel.size() && channel[from] == '/') ++from;  // ROS's leading '/': "/tf" -> "tf"
  std::string out;
  for (size_t i = from; i < channel.size(); ++i) {
    const auto c = static_cast<unsigned char>(channel[i]);
    const bool plain = std::isalnum(c) || c == '_' || c == '-' || (c == '.' && !out.empty());
    out += plain ? static_cast<char>(c) : '_';
  }
  if (out.empty()) out = "channel";  // the empty name, or only slashes
  constexpr size_t kMax = 200;
  if (out.size() > kMax) out = out.substr(0, kMax - 17) + "~" + name_hash(channel);
  return out;
}

Result<CsvExport> export_csv(const CsvExportOptions& a) {
  ReadOptions ro;
  ro.channels = a.channels;
  auto reader = LogReader::open(a.log, ro);
  if (!reader) return reader.error();
  std::error_code ec;
  fs::create_directories(a.out, ec);
  if (ec) return Error{a.out + ": cannot create: " + ec.message(), ErrorCode::kCannotWrite};
  std::map<std::string, CsvFile, std::less<>> files;
  std::set<std::string> file_names;  // taken, for channels that map to one name
  CsvExport done;
  lcmtypes::FlattenOptions fo;
  fo.max_array = a.max_array;
  fo.bytes = a.bytes;
  auto close_all = [&](bool keep) {
    for (auto& [name, f] : files) {
      if (f.f != nullptr) std::fclose(f.f);
      f.f = nullptr;
      if (!keep) fs::remove(f.path + ".partial", ec);
    }
  };
  // One file per channel, but not one open file per channel: a log with more channels than the open-file limit
  // failed ("cannot create", no reason). When the limit is met the file unused longest is closed, and reopened to
  // append when its channel comes again.
  uint64_t clock = 0;
  auto open_file = [&](CsvFile& f, const char* mode) -> Status {
    for (;;) {
      f.f = std::fopen((f.path + ".partial").c_str(), mode);
      if (f.f != nullptr) return {};
      const int err = errno;
      CsvFile* oldest = nullptr;
      for (auto& [name, g] : files) {
        if (g.f != nullptr && &g != &f && (oldest == nullptr || g.last_use < oldest->last_use)) oldest = &g;
      }
      if ((err != EMFILE && err != ENFILE) || oldest == nullptr) {
        return Error{f.path + ".partial: cannot " + (*mode == 'w' ? "create" : "reopen") + ": " + std::strerror(err),
                     ErrorCode::kCannotWrite};
      }
      const bool ok = std::fclose(oldest->f) == 0;
      oldest->f = nullptr;
      if (!ok) return Error{oldest->path + ".partial: write failed (disk full?)", ErrorCode::kCannotWrite};
    }
  };
  Event e;
  std::vector<std::pair<std::string, std::string>> values;
  while (reader->next(e)) {
    const char* type = lcmtypes::type_name(logfmt::fingerprint(e.data));
    const lcmtypes::StructDef* def = type != nullptr ? lcmtypes::find_struct(type) : nullptr;
    if (def == nullptr) {
      ++done.unknown[std::string(e.channel)];
      continue;
    }
    if (auto problem = lcmtypes::layout_problem(e.data)) {  // cut short or lying about a length: no row of it
      auto& [n, first] = done.malformed[std::string(e.channel)];
      if (n++ == 0) first = *problem;
      continue;
    }
    values.clear();
    lcmtypes::flatten(
        *def, e.data, [&](const std::string& c, const std::string& v) { values.emplace_back(c, v); }, fo);
    auto it = files.find(e.channel);
    if (it == files.end()) {
      CsvFile f;
      f.path = (fs::path(a.out) / (unique_channel_file_name(e.channel, &file_names) + ".csv")).string();
      if (Status st = open_file(f, "w"); !st) {
        close_all(false);
        return st.error();
      }
      for (const auto& [c, v] : values) {
        if (f.column.emplace(c, f.names.size()).second) f.names.push_back(c);
      }
      f.header_columns = f.names.size();
      write_header(f.f, f.names);
      it = files.emplace(std::string(e.channel), std::move(f)).first;
    }
    CsvFile& f = it->second;
    f.last_use = ++clock;
    if (f.f == nullptr) {
      if (Status st = open_file(f, "a"); !st) {
        close_all(false);
        return st.error();
      }
    }
    for (auto& cell : f.row) cell.clear();
    for (const auto& [c, v] : values) {
      auto [k, added] = f.column.emplace(c, f.names.size());
      if (added) f.names.push_back(c);
      if (f.row.size() < f.names.size()) f.row.resize(f.names.size());
      f.row[k->second] = csv_quote(v);
    }
    std::fprintf(f.f, "%.6f", Time::from_us(e.utime).seconds());
    for (const auto& cell : f.row) {
      std::fputc(',', f.f);
      std::fputs(cell.c_str(), f.f);
    }
    std::fputc('\n', f.f);
    ++f.rows;
    if (std::ferror(f.f)) {
      close_all(false);
      return Error{f.path + ".partial: write failed (disk full?)", ErrorCode::kCannotWrite};
    }
  }
  for (auto& [name, f] : files) {  // all closed first: widen() needs two files open
    const bool ok = f.f == nullptr || std::fclose(f.f) == 0;
    f.f = nullptr;
    if (!ok) {
      close_all(false);
      return Error{f.path + ".partial: write failed (disk full?)", ErrorCode::kCannotWrite};
    }
  }
  for (auto& [name, f] : files) {
    if (f.names.size() > f.header_columns) {
      if (Status st = widen(f); !st) {
        close_all(false);
        return st.error();
      }
    }
    fs::rename(f.path + ".partial", f.path, ec);
    if (ec) return Error{f.path + ": cannot rename into place: " + ec.message(), ErrorCode::kCannotWrite};
  }
  for (const auto& [name, f] : files) done.files.push_back({name, f.path, f.rows});
  done.problems = reader->problems();
  return done;
}

std::string export_text(const CsvExport& e, const std::string& log) {
  std::string out;
  for (const auto& f : e.files)
    appendf(out, "%-24s %10s rows  %s\n", f.channel.c_str(), thousands(f.rows).c_str(), f.path.c_str());
  for (const auto& [name, m] : e.malformed) {
    appendf(out, "%-24s %10s malformed messages skipped (first: %s)\n", name.c_str(), thousands(m.first).c_str(),
            m.second.c_str());
  }
  for (const auto& [name, n] : e.unknown) {
    appendf(out, "%-24s %10s messages of a type that is not driftlab's: skipped\n", name.c_str(), thousands(n).c_str());
  }
  if (e.problems > 0) {
    appendf(out, "%s: %llu damaged spots skipped (driftlab info lists them)\n", log.c_str(),
            static_cast<unsigned long long>(e.problems));
  }
  return out;
}

}  // namespace driftlab::formats
