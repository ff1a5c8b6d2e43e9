// driftlab import rawlog / export rawlog: MRPT rawlogs in and out, so MRPT's datasets replay through driftlab and
// MRPT's tools (icp-slam, RawLogViewer) read driftlab's logs.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <memory>

#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/same_file.h"
#include "core/wall_clock.h"
#include "recordings/log_input.h"
#include "slam/rawlog.h"

namespace driftlab::apps {
namespace {

struct RawlogArgs {
  std::string in, out;
};

void print_counts(const slam::RawlogCounts& c, const std::string& from, const std::string& to) {
  int64_t total = 0;
  for (const auto& [name, n] : c.written) total += n;
  std::printf("%s -> %s: %s written\n", from.c_str(), to.c_str(), thousands(total).c_str());
  for (const auto& [name, n] : c.written) std::printf("  %-28s %s\n", name.c_str(), thousands(n).c_str());
  for (const auto& [name, n] : c.skipped) {
    std::printf("  skipped %-20s %s (no counterpart)\n", name.c_str(), thousands(n).c_str());
  }
}

}  // namespace

void add_rawlog_commands(CLI::App& import, CLI::App& exp, int* exit_code) {
  auto in = std::make_shared<RawlogArgs>();
  CLI::App* from = import.add_subcommand("rawlog", tool_description("import", "rawlog"));
  from->footer("2D scans go to SCAN (sensor poses on TF_STATIC), odometry to ODOM, IMU to IMU, robot poses to\n"
               "GROUND_TRUTH; event times are the observation timestamps. See docs/slam.md.");
  from->add_option("rawlog", in->in, "Rawlog to read")->required();
  from->add_option("-o,--out", in->out, "Log to write")->required();
  from->callback([in, exit_code] {
    if (Status s = refuse_same_file(in->out, {in->in}); !s) {
      *exit_code = fail(s.message());
      return;
    }
    auto r = slam::import_rawlog(in->in, in->out);
    if (!r) {
      *exit_code = fail(r.error().message, exit_code_for(r.error()));
      return;
    }
    print_counts(*r, in->in, in->out);
    if (r->one_stamp > 0) {
      // Converted (a SLAM run still sees the scans in order), but its times mean nothing: said, and exit 2.
      std::fprintf(stderr,
                   "driftlab: %s: warning: all %s observations carry one timestamp (%s), as MRPT 2.5's "
                   "carmen2rawlog writes them: the log's times, rates and latencies mean nothing\n",
                   in->in.c_str(), thousands(r->one_stamp).c_str(), format_utime(r->one_stamp_us).c_str());
      *exit_code = kExitBadInput;
    }
  });

  auto out = std::make_shared<RawlogArgs>();
  CLI::App* to = exp.add_subcommand("rawlog", tool_description("export", "rawlog"));
  to->footer("Laser scans, odometry, IMU and GROUND_TRUTH poses become MRPT observations, stamped with their header\n"
             "stamps, in log order; icp-slam and RawLogViewer read the result.");
  to->add_option("log", out->in, "Log to read")->required();
  to->add_option("-o,--out", out->out, "Rawlog to write")->required();
  to->callback([out, exit_code] {
    if (Status s = refuse_same_file(out->out, {out->in}); !s) {
      *exit_code = fail(s.message());
      return;
    }
    auto log = recordings::event_log_for(out->in);  // another tool's recording: its cached conversion
    if (!log) {
      *exit_code = fail(log.error().message, exit_code_for(log.error()));
      return;
    }
    auto r = slam::export_rawlog(*log, out->out);
    if (!r) {
      *exit_code = fail(r.error().message, exit_code_for(r.error()));
      return;
    }
    print_counts(*r, out->in, out->out);
  });
}

}  // namespace driftlab::apps
