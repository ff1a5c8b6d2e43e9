// runtime/module_report.h: a run's module reports as replay and run print them (JSON and text), and the JSON read
// back as the demo and the batches read a replay's.
#include "runtime/module_report.h"

#include <gtest/gtest.h>

namespace driftlab::runtime {
namespace {

std::vector<ModuleReport> reports() {
  ModuleReport est;
  est.name = "estimator";
  est.inputs = 12345;
  est.late = 12;
  est.outputs = 600;
  est.proc_mean_s = 0.00012;
  est.proc_p95_s = 0.0004;
  est.queue_depth_max = 3;
  est.warnings = {"IMU: 3 messages with NaN dropped"};
  est.metrics = {{"late_rejected", 1195}, {"innovation_rms", 0.0123456}};
  ModuleReport slam;
  slam.name = "slam";
  return {est, slam};
}

TEST(ModuleReport, TheJsonReadsBackAndTheTextSaysWhatItHas) {
  const nlohmann::json j = {{"modules", to_json(reports())}};
  auto back = module_reports_from_json(j);
  ASSERT_TRUE(back) << back.error().message;
  ASSERT_EQ(back->size(), 2u);
  const ModuleReport& est = (*back)[0];
  EXPECT_EQ(est.name, "estimator");
  EXPECT_EQ(est.inputs, 12345);
  EXPECT_EQ(est.queue_depth_max, 3);
  EXPECT_EQ(est.warnings, reports()[0].warnings);
  EXPECT_EQ(metric(est, "late_rejected"), 1195);
  EXPECT_NEAR(metric(est, "innovation_rms").value_or(0), 0.0123456, 1e-12);
  EXPECT_FALSE(metric(est, "absent"));

  EXPECT_EQ(module_report_text(reports(), false),
            "  estimator  12,345 inputs (12 late, 0 out of order, 0 dropped), 600 outputs\n"
            "            late_rejected 1195, innovation_rms 0.01235\n"
            "  warning: IMU: 3 messages with NaN dropped\n"
            "  slam       0 inputs (0 late, 0 out of order, 0 dropped), 0 outputs\n");
  EXPECT_NE(module_report_text(reports(), true).find(", 0.120 ms per input (p95 0.400 ms), queue <= 3\n"),
            std::string::npos);

  nlohmann::json broken = j;
  broken["modules"][0].erase("inputs");
  auto bad = module_reports_from_json(broken);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("not the module reports of driftlab replay --json"), std::string::npos);
  EXPECT_FALSE(module_reports_from_json(nlohmann::json::object()));
}

TEST(LiveReport, WhatRunPrints) {
  const LiveOptions options{.url = "udpm://239.255.76.67:7667?ttl=0", .out = "out.lcm"};
  const LiveReport report{.received = 4200, .outputs = 310, .wall_s = 12.5, .modules = reports()};
  const std::string text = live_text(options, report, {"slam: auto backend: 2d"});
  EXPECT_EQ(text.rfind("slam: auto backend: 2d\nran 12.5 s on udpm://239.255.76.67:7667?ttl=0: 4,200 messages handled, "
                       "310 module outputs -> out.lcm\n  estimator  12,345 inputs",
                       0),
            0u)
      << text;
  EXPECT_NE(text.find("0.120 ms per input"), std::string::npos);  // live, processing time is always measured
  const nlohmann::json j = to_json(options, report, {});
  EXPECT_EQ(j["received"], 4200);
  EXPECT_EQ(j["out"], "out.lcm");
  auto back = module_reports_from_json(j);  // the demo and the batches read a run's reports as a replay's
  ASSERT_TRUE(back);
  EXPECT_EQ(back->size(), 2u);
}

}  // namespace
}  // namespace driftlab::runtime
