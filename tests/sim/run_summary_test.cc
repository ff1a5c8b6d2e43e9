// sim/run_summary.h: what `driftlab sim` and `driftlab replay --closed-loop` print of a run, from a report.
#include "sim/run_summary.h"

#include <gtest/gtest.h>

namespace driftlab::sim {
namespace {

SimRun ground_run() {
  SimRun run;
  run.scenario_path = "sim/scenarios/indoor.yaml";
  run.scenario_name = "indoor";
  run.out = "run.lcm";
  run.wall_s = 2;
  run.report.simulated_s = 20;
  run.report.messages = {{"IMU", 4000}, {"SCAN", 200}};
  run.report.faults_json = "run.lcm.faults.json";
  run.report.distance_m = 7.5;
  run.report.laps = 1;
  run.report.odometry_error_m = 0.125;
  return run;
}

TEST(SimRun, TheLinesAndTheJsonOfARun) {
  SimRun run = ground_run();
  EXPECT_EQ(sim_run_text(run),
            "simulated 20.0 s of indoor in 2.00 s (10x real time): 4,200 messages to run.lcm\n"
            "  IMU                  4,000\n"
            "  SCAN                 200\n"
            "drove 7.5 m (1 laps); odometry is 0.12 m off the truth at the end\n"
            "injected faults: run.lcm.faults.json\n");
  const nlohmann::json j = to_json(run);
  EXPECT_EQ(j["real_time_factor"], 10.0);
  EXPECT_EQ(j["messages"]["IMU"], 4000);
  EXPECT_EQ(j["scenario"], "sim/scenarios/indoor.yaml");
  // A drone drives no route: no drive line; its run's notes are said; an interrupted run says so.
  run.ground_robot = false;
  run.report.interrupted = true;
  run.report.notes = {"took off at 1.0 s"};
  const std::string text = sim_run_text(run);
  EXPECT_EQ(text.rfind("interrupted after 20.0 s", 0), 0u) << text;
  EXPECT_EQ(text.find("drove"), std::string::npos) << text;
  EXPECT_NE(text.find("\ntook off at 1.0 s\ninjected faults:"), std::string::npos) << text;
}

TEST(ClosedLoopRun, SaysWhatWasCorrectedOrThatNothingWas) {
  ClosedLoopRun c{"sim.lcm", ground_run(), {}, {}};
  c.run.out = "again.lcm";
  EXPECT_EQ(closed_loop_text(c),
            "no corrections: the run is the log's simulation again\n"
            "ran 20.0 s of indoor in closed loop in 2.00 s: 4,200 messages -> again.lcm\n");
  c.corrections.clocks["IMU"] = {.offset_s = 0.11, .drift_ppm = 0};
  c.corrections.retime["ARM_CMD"] = Duration::from_us(120000);
  c.notes = {"restamping IMU: 110.0 ms ahead"};
  const std::string text = closed_loop_text(c);
  EXPECT_EQ(text.rfind("restamping IMU: 110.0 ms ahead\nran 20.0 s", 0), 0u) << text;
  const nlohmann::json j = to_json(c);
  EXPECT_EQ(j["log"], "sim.lcm");
  EXPECT_EQ(j["out"], "again.lcm");
  EXPECT_EQ(j["restamp"]["IMU"]["offset_s"], 0.11);
  EXPECT_EQ(j["retime"]["ARM_CMD"], 0.12);
}

}  // namespace
}  // namespace driftlab::sim
