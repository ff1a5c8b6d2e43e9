// `driftlab eval --relations` on the SLAM benchmark's real data: GMapping's corrected Intel and ACES trajectories
// scored against the benchmark's relations, equal to an independent numpy/scipy reference
// (tests/analyzers/relations_reference.py) and in the range the literature gives for GMapping.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "analyzers/trajectory.h"
#include "analyzers/trajectory_io.h"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/pose_t.hpp"
#include "lcmtypes/validate.h"
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

/// GMapping's corrected poses at the raw scans' stamps. The corrected CARMEN log counts time from 0 with six
/// significant digits and holds only the scans GMapping integrated; its readings are the raw ones, unchanged, so
/// each corrected scan is found among the raw scans by its readings (data README), and its pose takes that stamp.
analyzers::Trajectory corrected_at_raw_stamps(const std::string& raw_log, const std::string& corrected_log) {
  std::map<std::vector<float>, int64_t> stamp_of;
  size_t raw_scans = 0;
  for (const auto& e : test::read_all(raw_log)) {
    if (e.channel != "/scan") continue;
    laser_scan_t s;
    EXPECT_TRUE(lcmtypes::decode(e.data, s));
    stamp_of.emplace(s.ranges, s.header.utime);
    ++raw_scans;
  }
  EXPECT_EQ(stamp_of.size(), raw_scans) << "two raw scans with the same readings: matching would be ambiguous";
  std::vector<std::vector<float>> scans;
  std::vector<pose_t> poses;
  for (const auto& e : test::read_all(corrected_log)) {
    if (e.channel == "FLASER") {
      laser_scan_t s;
      EXPECT_TRUE(lcmtypes::decode(e.data, s));
      scans.push_back(s.ranges);
    } else if (e.channel == "FLASER_POSE") {
      pose_t p;
      EXPECT_TRUE(lcmtypes::decode(e.data, p));
      poses.push_back(p);
    }
  }
  EXPECT_EQ(scans.size(), poses.size());  // one pose per FLASER line
  analyzers::Trajectory t;
  for (size_t i = 0; i < scans.size() && i < poses.size(); ++i) {
    const auto it = stamp_of.find(scans[i]);
    if (it == stamp_of.end()) {
      ADD_FAILURE() << "corrected scan " << i << " is not among the raw scans";
      continue;
    }
    const auto& p = poses[i];
    t.push_back(static_cast<double>(it->second) * 1e-6, {p.position.x, p.position.y, p.position.z},
                {p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z});
  }
  analyzers::sort_by_stamp(t);
  return t;
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
  const std::string base = std::string("carmen/") + run.name;
  const std::string bag = test::shared_data(base + ".orig.bag");
  const std::string corrected = test::shared_data(base + "-corrected.log.gz");
  const std::string relations = test::shared_data(base + ".relations");
  if (bag.empty() || corrected.empty() || relations.empty()) return;
  test::TempDir dir;
  ASSERT_NO_FATAL_FAILURE(import(bag, dir.file("raw.lcm")));
  ASSERT_NO_FATAL_FAILURE(import(corrected, dir.file("corrected.lcm")));
  const analyzers::Trajectory gmapping = corrected_at_raw_stamps(dir.file("raw.lcm"), dir.file("corrected.lcm"));
  ASSERT_TRUE(analyzers::write_tum(dir.file("gmapping.tum"), gmapping).ok());
  ASSERT_EQ(test::run(kDriftlab + " export tum " + dir.file("raw.lcm") + ":/odom -o " + dir.file("odom.tum")), 0);

  for (const bool with_odometry : {false, true}) {
    SCOPED_TRACE(with_odometry ? "with odometry" : "stamps only");
    std::string ours_text, ref_text;
    ASSERT_EQ(test::run(kDriftlab + " eval --est " + dir.file("gmapping.tum") + " --relations " + relations +
                            (with_odometry ? " --relations-odometry " + dir.file("odom.tum") : "") +
                            " --json -",
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
