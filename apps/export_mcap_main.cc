// driftlab export mcap / export rosbag2: a log as a ROS 2 bag in MCAP storage, for Foxglove and `ros2 bag play`.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>

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

constexpr int kProblemLines = 20;

/// The findings of `driftlab diagnose --json` as one Metadata record: per channel its verdict and reasons.
Result<formats::McapMetadata> diagnosis_metadata(const std::string& path) {
  auto text = read_text_file(path, "diagnosis");
  if (!text) return text.error();
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(*text);
  } catch (const nlohmann::json::exception& e) {
    return Error(path + ": not JSON: " + e.what());
  }
  if (!j.is_object() || !j.contains("channels") || !j["channels"].is_array()) {
    return Error(path + ": not a diagnosis (driftlab diagnose --json writes one)");
  }
  formats::McapMetadata m{"driftlab.diagnosis", {}};
  for (const auto& c : j["channels"]) {
    if (!c.is_object() || !c.contains("name") || !c["name"].is_string()) continue;
    std::string text = c.value("verdict", std::string("ok"));
    if (c.contains("reasons") && c["reasons"].is_array()) {
      for (const auto& r : c["reasons"])
        if (r.is_string()) text += "; " + r.get<std::string>();
    }
    m.entries.emplace_back(c["name"].get<std::string>(), text);
  }
  return m;
}

int run_mcap(const McapArgs& a) {
  if (Status s = refuse_same_file(a.out, a.inputs, "-o", a.folder ? OutputKind::kFolder : OutputKind::kFile); !s)
    return fail(s.message());
  auto log = recordings::event_log_for(a.inputs);
  if (!log) return fail(log.error().message, exit_code_for_input(log.error()));
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
  int printed = 0;
  int64_t problems = 0;
  auto on_problem = [&](const std::string& line) {
    ++problems;
    if (printed++ < kProblemLines) std::fprintf(stderr, "driftlab: %s\n", line.c_str());
  };
  auto r = a.folder ? formats::export_rosbag2(*log, a.out, o, on_problem)
                    : formats::export_mcap(*log, a.out, o, on_problem);
  if (!r) return fail(r.error().message, kExitFailure);
  if (problems > kProblemLines) std::fprintf(stderr, "driftlab: %s more problems\n", thousands(problems - kProblemLines).c_str());
  std::printf("%s -> %s: %s messages, %s\n", a.inputs[0].c_str(), a.out.c_str(), thousands(r->messages).c_str(),
              human_bytes(static_cast<double>(r->bytes)).c_str());
  size_t width = 8;
  for (const auto& t : r->topics) width = std::max(width, t.topic.size());
  for (const auto& t : r->topics) {
    std::printf("  %-*s %-28s -> %-42s %10s%s\n", static_cast<int>(width), t.topic.c_str(), t.driftlab_type.c_str(),
                (t.ros_type + (t.encoding == "cdr" ? "" : " (" + t.encoding + ")")).c_str(),
                thousands(t.messages).c_str(), t.topic == t.channel ? "" : ("  (channel " + t.channel + ")").c_str());
  }
  for (const auto& [c, n] : r->skipped) {
    std::printf("  skipped %s: %s messages of a type driftlab does not know\n", c.c_str(), thousands(n).c_str());
  }
  return problems > 0 ? kExitBadInput : kExitOk;
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
