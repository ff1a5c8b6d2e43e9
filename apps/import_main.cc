// driftlab import FILE -o OUT.lcm: another tool's log into a driftlab log, the format taken from the content.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <functional>
#include <memory>

#include "analyzers/flight_log_pair.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/same_file.h"
#include "formats/import.h"
#include "recordings/log_input.h"

namespace driftlab::apps {
namespace {

struct ImportArgs {
  std::vector<std::string> in;
  std::string out;
};

}  // namespace

void add_import_file_command(CLI::App& import, int* exit_code) {
  auto args = std::make_shared<ImportArgs>();
  import.require_subcommand(0, 1);
  import.footer(
      "The format is recognised from the content: ROS 1 bags (format 2.0; uncompressed, bz2 or lz4 chunks; indexed\n"
      "or not), ROS 2 bags (a folder with metadata.yaml, or one .db3 or .mcap file; zstd-compressed files or\n"
      "messages), MCAP files (chunks uncompressed, zstd or lz4), CARMEN logs (.log/.clf, plain or gzip), PX4\n"
      "flight logs (ULog, .ulg) and MRPT rawlogs. The files of a split recording are one recording: give its folder\n"
      "or all of its files. Header stamps become header.utime, the recording's receive times the event times (a\n"
      "ULog message: timestamp_sample, or timestamp, and its timestamp). Topics keep their names as channels (a\n"
      "ULog topic logged in several instances: name/instance). A flight log (ULog) given beside a bag of the same\n"
      "flight is put on the bag's clock (by the bag's time sync, their IMUs or GNSS time) and both go into one log.\n"
      "See docs/import.md.");
  import.add_option("file", args->in,
                    "Log to convert (a bag folder, or the files of one recording; a flight log beside a bag)");
  import.add_option("-o,--out", args->out, "Log to write");
  import.callback([&import, args, exit_code] {
    if (import.get_subcommands().size() > 0) return;  // import rawlog
    if (args->in.empty() || args->out.empty()) {
      *exit_code = fail("import: give a FILE and -o OUT.lcm (see 'driftlab import --help')");
      return;
    }
    if (Status s = refuse_same_file(args->out, args->in); !s) {
      *exit_code = fail(s.message());
      return;
    }
    if (args->in.size() == 1 && formats::detect_format(args->in[0]).format == formats::Format::kMrptRawlog) {
      // MRPT's rawlogs are read by MRPT itself, in the program that links it.
      std::vector<std::string> argv = {"driftlab", "import", "rawlog", args->in[0], "-o", args->out};
      std::vector<char*> c;
      for (auto& a : argv) c.push_back(a.data());
      c.push_back(nullptr);
      if (const ToolCommand* tool = find_tool(static_cast<int>(argv.size()), c.data())) {
        *exit_code = exec_tool(*tool, c.data());
      }
      return;
    }
    recordings::ProblemLines problems(args->in[0]);
    std::string alignment;
    auto r = analyzers::import_recording(args->in, args->out, std::ref(problems), &alignment);
    if (!r) {
      *exit_code = fail(r.error().message, exit_code_for(r.error()));
      return;
    }
    problems.finish();
    std::string from = args->in[0];
    if (args->in.size() > 1) from += " and " + std::to_string(args->in.size() - 1) + " more";
    std::fputs(formats::import_text(*r, from, args->out).c_str(), stdout);
    if (!alignment.empty()) std::printf("%s\n", alignment.c_str());
    // Everything intact is in the log; the exit code still says that not all of the file was.
    if (r->problems > 0) *exit_code = kExitBadInput;
  });
}

}  // namespace driftlab::apps
