// driftlab export mcap / export rosbag2: a log as a ROS 2 bag in MCAP storage, for Foxglove and `ros2 bag play`.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>

#include "analyzers/diagnosis_json.h"
#include "apps/cli_checks.h"
#include "apps/cli_util.h"
#include "apps/commands.h"
#include "core/same_file.h"
#include "core/text_file.h"
#include "formats/export_mcap.h"
#include "recordings/log_input.h"

namespace driftlab::apps {
namespace {

struct McapArgs {
  std::vector<std::string> inputs;
  std::string out, compression = "zstd", diagnosis, channels;
  int level = 1;
  double chunk_mb = 4;
  bool folder = false;  // export rosbag2
};

/// The findings of `driftlab diagnose --json` as one Metadata record: per channel its verdict and reasons.
Result<formats::McapMetadata> diagnosis_metadata(const std::string& path) {
  auto text = read_text_file(path, "diagnosis");
  if (!text) return text.error();
  const nlohmann::json j = nlohmann::json::parse(*text, nullptr, false);
  auto summary = j.is_discarded() ? Result<analyzers::DiagnosisSummary>(Error{"not JSON"}) : analyzers::summarize(j);
  if (!summary) return Error{path + ": " + summary.error().message};
  formats::McapMetadata m{"driftlab.diagnosis", {}};
  for (const auto& stream : summary->streams) {
    std::string said = analyzers::severity_name(stream.verdict);
    for (const auto& r : stream.reasons) said += "; " + r;
    m.entries.emplace_back(stream.name, said);
  }
  return m;
}

int run_mcap(const McapArgs& a) {
  if (Status s = refuse_same_file(a.out, a.inputs, "-o", a.folder ? OutputKind::kFolder : OutputKind::kFile); !s)
    return fail(s.message());
  auto log = recordings::event_log_for(a.inputs);
  if (!log) return fail(log.error().message, exit_code_for(log.error()));
  formats::McapExportOptions o;
  o.compression = a.compression == "zstd"  ? formats::McapCompression::kZstd
                  : a.compression == "lz4" ? formats::McapCompression::kLz4
                                           : formats::McapCompression::kNone;
  o.level = a.compression == "lz4" && a.level == 1 ? 0 : a.level;
  o.chunk_bytes = static_cast<size_t>(a.chunk_mb * (1 << 20));
  o.channels = a.channels;
  if (!a.diagnosis.empty()) {
    auto m = diagnosis_metadata(a.diagnosis);
    if (!m) return fail(m.error().message);
    o.metadata.push_back(std::move(*m));
  }
  recordings::ProblemLines problems(a.inputs[0]);
  auto r = a.folder ? formats::export_rosbag2(*log, a.out, o, std::ref(problems))
                    : formats::export_mcap(*log, a.out, o, std::ref(problems));
  if (!r) return fail(r.error().message, exit_code_for(r.error()));
  problems.finish();
  std::fputs(formats::export_text(*r, a.inputs[0], a.out).c_str(), stdout);
  return problems.count() > 0 ? kExitBadInput : kExitOk;
}

}  // namespace

void add_export_mcap_commands(CLI::App& exp, int* exit_code) {
  for (const bool folder : {false, true}) {
    auto a = std::make_shared<McapArgs>();
    a->folder = folder;
    CLI::App* c = exp.add_subcommand(folder ? "rosbag2" : "mcap",
                                     folder ? "A log as a ROS 2 bag folder (metadata.yaml and an MCAP file)."
                                            : "A log as an MCAP file: a ROS 2 bag for Foxglove and ros2 bag play.");
    c->footer(
        "driftlab's types become the standard ROS 2 messages (LaserScan, Imu, PointCloud2, Image, CompressedImage,\n"
        "JointState, Odometry, PoseWithCovarianceStamped, TFMessage, TwistStamped) in CDR with their exact ros2msg\n"
        "schemas; messages imported from another recording go back out as they came; other driftlab types go out\n"
        "as CDR with schemas made from lcmtypes/ (driftlab_msgs/msg/...). The event time is the log time, header.seq\n"
        "the MCAP sequence. Chunks, message indexes, summary and CRCs as the MCAP specification has them. Channel\n"
        "names that are not ROS names get one (the original is kept in the channel's metadata). See docs/export.md.");
    c->add_option("log", a->inputs, kLogInputHelp)->required();
    c->add_option("-o,--out", a->out, folder ? "Bag folder to write (new or empty)" : "MCAP file to write")->required();
    c->add_option("-c,--channels", a->channels, "Only channels fully matching this regex (ECMAScript)");
    c->add_option("--compression", a->compression, "Chunk compression")
        ->capture_default_str()
        ->check(CLI::IsMember({"zstd", "lz4", "none"}));
    c->add_option("--level", a->level, "zstd level (1: fast, 19: small)")
        ->capture_default_str()
        ->check(in_range(config::between(-7, 22)));
    c->add_option("--chunk-mb", a->chunk_mb, "Uncompressed size of a chunk [MiB]")
        ->capture_default_str()
        ->check(in_range(config::between(0.001, 1024), "MiB"));
    c->add_option("--diagnosis", a->diagnosis,
                  "Also carry a diagnosis (driftlab diagnose --json) as the file's driftlab.diagnosis metadata");
    c->callback([a, exit_code] { *exit_code = run_mcap(*a); });
  }
}

}  // namespace driftlab::apps
