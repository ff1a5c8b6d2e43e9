// driftlab export tum / export csv: trajectories for evo, every channel as a table for PlotJuggler and
// spreadsheets. (export rawlog lives with import rawlog in rawlog_main.cc.)
#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <memory>

#include "analyzers/trajectory_io.h"
#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/same_file.h"
#include "core/time.h"
#include "core/wall_clock.h"
#include "formats/export_csv.h"
#include "recordings/log_input.h"

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

int run_csv(const CsvArgs& a) {
  auto done = formats::export_csv(
      {.log = a.log, .out = a.out, .channels = a.channels, .max_array = a.max_array, .bytes = a.bytes});
  if (!done) return fail(done.error().message, exit_code_for(done.error()));
  std::fputs(formats::export_text(*done, a.log).c_str(), stdout);
  if (done->files.empty()) return fail(a.log + ": no channel of a driftlab type to export");
  return kExitOk;
}

int run_tum(TumArgs a) {
  if (a.channel.empty() && !analyzers::split_log_channel(a.log, &a.log, &a.channel)) {
    return fail(a.log + ": name the channel as LOG:CHANNEL (or with -c CHANNEL)");
  }
  if (Status s = refuse_same_file(a.out, {a.log}); !s) return fail(s.message());
  auto log = recordings::event_log_for(a.log);
  if (!log) return fail(log.error().message, exit_code_for(log.error()));
  auto t = analyzers::load_log_channel(*log, a.channel);
  if (!t) return fail(t.error().message);
  // In stamp order, as evo and every TUM reader expect (a log holds poses in arrival order: a late or reordered
  // message arrives after a newer one); said when it changed anything.
  const analyzers::StampOrder order = analyzers::sort_by_stamp(*t);
  if (auto s = analyzers::write_tum(a.out, *t); !s) return fail(s.message(), exit_code_for(s.error()));
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
    auto log = recordings::event_log_for(csv->inputs);
    if (!log) {
      *exit_code = fail(log.error().message, exit_code_for(log.error()));
      return;
    }
    csv->log = *log;
    *exit_code = run_csv(*csv);
  });
}

}  // namespace driftlab::apps
