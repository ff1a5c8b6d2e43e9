// `driftlab eval --relations` on the SLAM benchmark's real data: GMapping's corrected Intel and ACES trajectories
// scored against the benchmark's relations, equal to an independent numpy/scipy reference
// (tests/analyzers/relations_reference.py) and in the range the literature gives for GMapping.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <string>

#include "analyzers/trajectory.h"
#include "analyzers/trajectory_io.h"
#include "tests/carmen_reference.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";
const std::string kReference =
    std::string(DRIFTLAB_PYTHON) + " " + DRIFTLAB_SOURCE_DIR + "/tests/analyzers/relations_reference.py";

void import(const std::string& in, const std::string& out) {
  const auto r = test::run_capture(kDriftlab + " import '" + in + "' -o '" + out + "'");
  ASSERT_EQ(r.code, 0) << r.err;
}

void expect_equal(const nlohmann::json& ours, const nlohmann::json& ref) {
  EXPECT_EQ(ours["relations"], ref["relations"]);
  EXPECT_EQ(ours["used"], ref["used"]);
  EXPECT_EQ(ours["bridged"], ref["bridged"]);
  EXPECT_NEAR(ours["max_bridge_s"].get<double>(), ref["max_bridge_s"].get<double>(), 1e-9);
  for (const char* group : {"trans_m", "trans_sq_m2", "rot_deg", "rot_sq_deg2"}) {
    for (const char* k : {"mean", "std", "max"}) {
      const double want = ref[group][k].get<double>();
      // Quaternions against 4x4 matrices, Eigen's slerp against scipy's: the same numbers to rounding.
      EXPECT_NEAR(ours[group][k].get<double>(), want, 1e-9 * std::max(1.0, std::abs(want))) << group << "." << k;
    }
  }
}

struct Dataset {
  const char* name;
  size_t relations;
  double published_rot_deg;  ///< GMapping's mean + one standard deviation of the rotation error in the paper [deg]
};

class RelationsOnTheBenchmark : public ::testing::TestWithParam<Dataset> {};

// GMapping's corrected trajectory holds 910 of Intel's 13,631 scans and 440 of ACES's 7,374: only 90 and 3
// relations have both scans in it. The benchmark's metric evaluator scores such logs by carrying the nearest
// corrected pose to each missing scan with the raw odometry (its -o option); --relations-odometry does the same.
TEST_P(RelationsOnTheBenchmark, GMappingAgreesWithTheReferenceAndTheLiterature) {
  const Dataset& run = GetParam();
  const auto files = test::carmen_run(run.name);
  if (files.empty()) return;
  const std::string& relations = files.relations;
  test::TempDir dir;
  ASSERT_NO_FATAL_FAILURE(import(files.bag, dir.file("raw.lcm")));
  ASSERT_NO_FATAL_FAILURE(import(files.corrected, dir.file("corrected.lcm")));
  auto gmapping = test::corrected_at_raw_stamps(dir.file("raw.lcm"), dir.file("corrected.lcm"));
  ASSERT_TRUE(gmapping) << gmapping.error().message;
  ASSERT_TRUE(analyzers::write_tum(dir.file("gmapping.tum"), *gmapping).ok());
  ASSERT_EQ(test::run(kDriftlab + " export tum " + dir.file("raw.lcm") + ":/odom -o " + dir.file("odom.tum")), 0);

  for (const bool with_odometry : {false, true}) {
    SCOPED_TRACE(with_odometry ? "with odometry" : "stamps only");
    std::string ours_text, ref_text;
    ASSERT_EQ(test::run(kDriftlab + " eval --est " + dir.file("gmapping.tum") + " --relations " + relations +
                            (with_odometry ? " --relations-odometry " + dir.file("odom.tum") : "") + " --json",
                        &ours_text),
              0)
        << ours_text;
    ASSERT_EQ(test::run(kReference + " " + dir.file("gmapping.tum") + " " + relations +
                            (with_odometry ? " --odometry " + dir.file("odom.tum") : ""),
                        &ref_text),
              0);
    const auto ours = nlohmann::json::parse(ours_text)["relations"];
    const auto ref = nlohmann::json::parse(ref_text);
    EXPECT_EQ(ours["relations"].get<size_t>(), run.relations);
    expect_equal(ours, ref);
    if (!with_odometry) continue;
    EXPECT_GT(ours["used"].get<double>(), 0.9 * static_cast<double>(run.relations));
    // Kuemmerle et al. (2009) give GMapping 0.031 +/- 0.026 m and 1.3 +/- 4.7 deg on Intel, 0.060 +/- 0.049 m
    // and 1.2 +/- 1.3 deg on ACES. Ours differs by the run (the corrected logs published on Radish, not
    // necessarily the paper's) and by the odometry carrying poses for up to seconds; it must still land in the
    // range the literature spans for GMapping on these two buildings (raw odometry is off by metres after a loop),
    // and its rotation error within one standard deviation of the published mean.
    const double mean = ours["trans_m"]["mean"].get<double>();
    EXPECT_GE(mean, 0.03);
    EXPECT_LE(mean, 0.06);
    EXPECT_LE(ours["rot_deg"]["mean"].get<double>(), run.published_rot_deg);
  }
}

INSTANTIATE_TEST_SUITE_P(Carmen, RelationsOnTheBenchmark,
                         ::testing::Values(Dataset{"intel", 2984, 1.3 + 4.7}, Dataset{"aces", 1279, 1.2 + 1.3}),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace driftlab
