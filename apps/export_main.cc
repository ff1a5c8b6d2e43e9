// driftlab export tum / export csv: trajectories for evo, every channel as a table for PlotJuggler and
// spreadsheets. (export rawlog lives with import rawlog in rawlog_main.cc.)
#include <CLI/CLI.hpp>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <set>

#include "analyzers/trajectory_io.h"
#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "apps/log_input.h"
#include "core/log_format.h"
#include "core/log_reader.h"
#include "core/same_file.h"
#include "core/time.h"
#include "lcmtypes/schema.h"
#include "lcmtypes/type_registry.h"
#include "lcmtypes/validate.h"

namespace driftlab::apps {
namespace {

namespace fs = std::filesystem;

struct TumArgs {
  std::string log, channel, out;
};

struct CsvArgs {
  std::vector<std::string> inputs;
  std::string log, out, channels;
  size_t max_array = 1024;
  bool bytes = false;
};

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
  if (in == nullptr) return Error{from + ": cannot read back: " + std::strerror(errno)};
  FILE* out = std::fopen(to.c_str(), "w");
  if (out == nullptr) {
    std::fclose(in);
    return Error{to + ": cannot create: " + std::strerror(errno)};
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
    return Error{to + ": write failed (disk full?)"};
  }
  std::error_code ec;
  fs::rename(to, from, ec);
  if (ec) return Error{from + ": cannot replace: " + ec.message()};
  return {};
}

int run_csv(const CsvArgs& a) {
  ReadOptions ro;
  ro.channels = a.channels;
  auto reader = LogReader::open(a.log, ro);
  if (!reader) return fail(reader.error().message);
  std::error_code ec;
  fs::create_directories(a.out, ec);
  if (ec) return fail(a.out + ": cannot create: " + ec.message());
  std::map<std::string, CsvFile, std::less<>> files;
  std::set<std::string> file_names;        // taken, for channels that map to one name
  std::map<std::string, int64_t> unknown;  // channel -> messages of a type without a definition here
  std::map<std::string, std::pair<int64_t, std::string>> malformed;  // channel -> count, the first one's problem
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
        return Error{f.path + ".partial: cannot " + (*mode == 'w' ? "create" : "reopen") + ": " + std::strerror(err)};
      }
      const bool ok = std::fclose(oldest->f) == 0;
      oldest->f = nullptr;
      if (!ok) return Error{oldest->path + ".partial: write failed (disk full?)"};
    }
  };
  Event e;
  std::vector<std::pair<std::string, std::string>> values;
  while (reader->next(e)) {
    const char* type = lcmtypes::type_name(logfmt::fingerprint(e.data));
    const lcmtypes::StructDef* def = type != nullptr ? lcmtypes::find_struct(type) : nullptr;
    if (def == nullptr) {
      ++unknown[std::string(e.channel)];
      continue;
    }
    if (auto problem = lcmtypes::layout_problem(e.data)) {  // cut short or lying about a length: no row of it
      auto& [n, first] = malformed[std::string(e.channel)];
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
        return fail(st.message(), kExitFailure);
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
        return fail(st.message(), kExitFailure);
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
      return fail(f.path + ".partial: write failed (disk full?)", kExitFailure);
    }
  }
  for (auto& [name, f] : files) {  // all closed first: widen() needs two files open
    const bool ok = f.f == nullptr || std::fclose(f.f) == 0;
    f.f = nullptr;
    if (!ok) {
      close_all(false);
      return fail(f.path + ".partial: write failed (disk full?)", kExitFailure);
    }
  }
  for (auto& [name, f] : files) {
    if (f.names.size() > f.header_columns) {
      if (Status st = widen(f); !st) {
        close_all(false);
        return fail(st.message(), kExitFailure);
      }
    }
    fs::rename(f.path + ".partial", f.path, ec);
    if (ec) return fail(f.path + ": cannot rename into place: " + ec.message(), kExitFailure);
  }
  for (const auto& [name, f] : files) {
    std::printf("%-24s %10s rows  %s\n", name.c_str(), thousands(f.rows).c_str(), f.path.c_str());
  }
  for (const auto& [name, m] : malformed) {
    std::printf("%-24s %10s malformed messages skipped (first: %s)\n", name.c_str(), thousands(m.first).c_str(),
                m.second.c_str());
  }
  for (const auto& [name, n] : unknown) {
    std::printf("%-24s %10s messages of a type that is not driftlab's: skipped\n", name.c_str(), thousands(n).c_str());
  }
  if (reader->problems() > 0) {
    std::printf("%s: %llu damaged spots skipped (driftlab info lists them)\n", a.log.c_str(),
                static_cast<unsigned long long>(reader->problems()));
  }
  if (files.empty()) return fail(a.log + ": no channel of a driftlab type to export");
  return kExitOk;
}

int run_tum(TumArgs a) {
  if (a.channel.empty() && !split_log_channel(a.log, &a.log, &a.channel)) {
    return fail(a.log + ": name the channel as LOG:CHANNEL (or with -c CHANNEL)");
  }
  if (Status s = refuse_same_file(a.out, {a.log}); !s) return fail(s.message());
  auto log = event_log_for(a.log);
  if (!log) return fail(log.error().message, exit_code_for_input(log.error()));
  auto t = analyzers::load_log_channel(*log, a.channel);
  if (!t) return fail(t.error().message);
  // In stamp order, as evo and every TUM reader expect (a log holds poses in arrival order: a late or reordered
  // message arrives after a newer one); said when it changed anything.
  const analyzers::StampOrder order = analyzers::sort_by_stamp(*t);
  const std::string partial = a.out + ".partial";
  if (auto s = analyzers::write_tum(partial, *t); !s) {
    std::error_code ec;
    fs::remove(partial, ec);
    return fail(s.message(), kExitFailure);
  }
  std::error_code ec;
  fs::rename(partial, a.out, ec);
  if (ec) return fail(a.out + ": cannot rename into place: " + ec.message(), kExitFailure);
  std::printf("%s:%s -> %s: %s poses", a.log.c_str(), a.channel.c_str(), a.out.c_str(),
              thousands(static_cast<int64_t>(t->size())).c_str());
  if (order.out_of_order > 0) {
    std::printf(" (sorted by stamp: %s arrived after a newer one, the first stamped %s)",
                thousands(static_cast<int64_t>(order.out_of_order)).c_str(),
                format_utime(Time::from_seconds_rounded(order.first_out_of_order).us()).c_str());
  }
  std::printf("\n");
  return kExitOk;
}

}  // namespace

void add_export_commands(CLI::App& exp, int* exit_code) {
  auto tum = std::make_shared<TumArgs>();
  CLI::App* t = exp.add_subcommand("tum", "A pose or odometry channel to a TUM trajectory file (for evo).");
  t->footer(
      "One line per pose: \"t x y z qx qy qz qw\", t the header stamp in seconds, in stamp order (poses that\n"
      "arrived out of order are sorted, and counted); evo_ape and evo_traj read it.");
  t->add_option("log", tum->log, "Log to read, as LOG:CHANNEL (or LOG with -c); LOG may be a bag (see export csv)")->required();
  t->add_option("-c,--channel", tum->channel, "Channel (driftlab.pose_t or driftlab.odometry_t)");
  t->add_option("-o,--out", tum->out, "TUM file to write")->required();
  t->callback([tum, exit_code] { *exit_code = run_tum(*tum); });

  auto csv = std::make_shared<CsvArgs>();
  CLI::App* c = exp.add_subcommand("csv", "Every channel to a CSV file of its own (for PlotJuggler, spreadsheets).");
  c->footer(
      "OUT/CHANNEL.csv per channel of a driftlab type, named as a person reads it (a leading '/' dropped, other\n"
      "characters than letters, digits, '_', '-' and '.' made '_': /tf -> tf.csv, /camera/image_raw ->\n"
      "camera_image_raw.csv; a second channel of the same name gets NAME~HASH.csv, HASH from its full name; the\n"
      "output lists each channel's file): log_time_s (arrival), then every field flattened by its\n"
      "definition in lcmtypes/ (header.seq, header.utime, orientation.w, ranges[0], ...), in the order of their\n"
      "first appearance in any of the channel's messages (a second transform, a longer scan add columns; a\n"
      "message without them leaves them empty). Files are written as .partial and renamed when complete.");
  c->add_option("log", csv->inputs, kLogInputHelp)->required();
  c->add_option("-o,--out", csv->out, "Folder to write the CSV files into")->required();
  c->add_option("-c,--channels", csv->channels, "Only channels fully matching this regex (ECMAScript)");
  c->add_option("--max-array", csv->max_array, "Arrays with more elements are left out (their length stays)")
      ->capture_default_str()
      ->check(in_range(config::between(0, 1e9)));
  c->add_flag("--bytes", csv->bytes, "Also write byte arrays (image data) as columns of numbers");
  c->callback([csv, exit_code] {
    if (Status s = refuse_same_file(csv->out, csv->inputs, "-o", OutputKind::kFolder); !s) {
      *exit_code = fail(s.message());
      return;
    }
    auto log = event_log_for(csv->inputs);
    if (!log) {
      *exit_code = fail(log.error().message, exit_code_for_input(log.error()));
      return;
    }
    csv->log = *log;
    *exit_code = run_csv(*csv);
  });
}

}  // namespace driftlab::apps
