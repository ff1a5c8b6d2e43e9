// replayer/replay_summary.h: what `driftlab replay` prints of a replay, from its report.
#include "replayer/replay_summary.h"

#include <gtest/gtest.h>

namespace driftlab::replay {
namespace {

TEST(ReplaySummary, TheLinesAndTheJsonOfAReplay) {
  ReplaySummary s;
  s.logs = {"a.lcm"};
  s.out = "out.lcm";
  s.wall_s = 0.5;
  s.notes = {"restamping IMU: 12.0 ms ahead"};
  s.restamp["IMU"] = {.offset_s = 0.012, .drift_ppm = 3};
  s.report.read = 1200;
  s.report.dispatched = 1100;
  s.report.outputs = 300;
  s.report.start_utime = 1000000;
  s.report.end_utime = 11000000;
  s.report.channels = {{"IMU", 1000}, {"SCAN", 100}};
  s.report.modules.push_back({.name = "estimator", .inputs = 1100, .outputs = 300});
  const std::string text = replay_text(s, false);
  EXPECT_EQ(text.rfind("restamping IMU: 12.0 ms ahead\n"
                       "replayed 10.0 s of log in 0.50 s (20x real time): 1,100 events in, 300 module outputs -> "
                       "out.lcm\n",
                       0),
            0u)
      << text;
  EXPECT_NE(text.find("estimator"), std::string::npos) << text;  // the module reports follow
  EXPECT_EQ(text.find("problems in the logs"), std::string::npos);
  const nlohmann::json j = to_json(s);
  EXPECT_EQ(j["replayed_s"], 10.0);
  EXPECT_EQ(j["real_time_factor"], 20.0);
  EXPECT_EQ(j["restamp"]["IMU"]["drift_ppm"], 3.0);
  EXPECT_EQ(j["modules"][0]["name"], "estimator");
  EXPECT_EQ(j["injected_faults"], 0);

  // Corruption met and faults injected are said; no output log, no arrow.
  s.out.clear();
  s.report.log_problems = 2;
  s.report.injected.resize(3);
  s.faults_channel = "FAULTS";
  const std::string more = replay_text(s, false);
  EXPECT_NE(more.find("300 module outputs\n  2 problems in the logs (see driftlab info)\n"
                      "  injected 3 faults (manifest on FAULTS)\n"),
            std::string::npos)
      << more;
}

}  // namespace
}  // namespace driftlab::replay
