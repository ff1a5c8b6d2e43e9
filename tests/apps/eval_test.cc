// End-to-end tests of `driftlab eval`: its numbers equal the evo-semantics reference (tests/analyzers/
// evo_reference.py, numpy) to 1e-6 on the same TUM files, and it works on log channels and explains failures.
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <random>

#include "analyzers/trajectory.h"
#include "analyzers/trajectory_io.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

using analyzers::Trajectory;

const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";
const std::string kReference =
    std::string(DRIFTLAB_PYTHON) + " " + DRIFTLAB_SOURCE_DIR + "/tests/analyzers/evo_reference.py";

/// Ground truth at 100 Hz along a 3D curve; the estimate at about 30 Hz with jittered stamps, a few gaps, a
/// rigid (or similarity) offset of its frame, slow drift and noise.
std::pair<Trajectory, Trajectory> make_pair(uint64_t seed, double est_rate, double scale) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  auto truth = [](double s) {
    return std::make_pair(Eigen::Vector3d(5 * std::cos(0.2 * s), 3 * std::sin(0.3 * s), 0.5 * std::sin(0.1 * s)),
                          Eigen::Quaterniond(Eigen::AngleAxisd(0.2 * s, Eigen::Vector3d(0.1, 0.1, 1).normalized())));
  };
  Trajectory gt, est;
  for (int i = 0; i < 6000; ++i) {
    const double s = 1700000000.0 + 0.01 * i;
    const auto [p, q] = truth(s - 1700000000.0);
    gt.push_back(s, p, q);
  }
  const Eigen::Matrix3d frame = Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.3, -0.2, 1).normalized()).toRotationMatrix();
  const Eigen::Vector3d shift(2.0, -1.0, 0.3);
  for (double s = 0.5; s < 59.5; s += 1.0 / est_rate) {
    if (std::fmod(s, 7.0) < 0.3) continue;  // a gap
    const double stamp = 1700000000.0 + s + 0.002 * noise(rng);
    const auto [p, q] = truth(s);
    const Eigen::Vector3d drifted = p * (1 + 0.002 * s) + 0.01 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    const Eigen::Quaterniond wobble(Eigen::AngleAxisd(0.01 * noise(rng), Eigen::Vector3d::UnitX()));
    est.push_back(stamp, scale * (frame * drifted) + shift, Eigen::Quaterniond(frame) * q * wobble);
  }
  return {gt, est};
}

void expect_stats_equal(const nlohmann::json& ours, const nlohmann::json& ref, const std::string& what) {
  for (const char* k : {"rmse", "mean", "median", "std", "min", "max"}) {
    EXPECT_NEAR(ours[k].get<double>(), ref[k].get<double>(), 1e-6) << what << "." << k;
  }
}

struct Case {
  std::string name;
  std::string args;  // shared by driftlab eval and the reference
  bool est_longer = false;
  double scale = 1.0;
  friend void PrintTo(const Case& c, std::ostream* os) { *os << c.name << ": " << c.args; }
};

class EvalEqualsEvoReference : public ::testing::TestWithParam<Case> {};

TEST_P(EvalEqualsEvoReference, OnTheSameTumFiles) {
  const Case& c = GetParam();
  test::TempDir dir;
  auto [gt, est] = make_pair(7, c.est_longer ? 150.0 : 30.0, c.scale);
  ASSERT_TRUE(analyzers::write_tum(dir.file("gt.tum"), gt).ok());
  ASSERT_TRUE(analyzers::write_tum(dir.file("est.tum"), est).ok());
  std::string ours_text, ref_text;
  ASSERT_EQ(test::run(kDriftlab + " eval --gt " + dir.file("gt.tum") + " --est " + dir.file("est.tum") + " " +
                          c.args + " --json -",
                      &ours_text),
            0);
  ASSERT_EQ(test::run(kReference + " " + dir.file("gt.tum") + " " + dir.file("est.tum") + " " + c.args, &ref_text), 0)
      << "the reference needs Debian's python3-numpy";
  const auto ours = nlohmann::json::parse(ours_text);
  const auto ref = nlohmann::json::parse(ref_text);
  ASSERT_GT(ref["matched"].get<int>(), 100);
  EXPECT_EQ(ours["matched"], ref["matched"]);
  EXPECT_EQ(ours["rpe"]["pairs"], ref["rpe"]["pairs"]);
  EXPECT_NEAR(ours["alignment"]["scale"].get<double>(), ref["alignment"]["scale"].get<double>(), 1e-9);
  for (int r = 0; r < 3; ++r) {
    EXPECT_NEAR(ours["alignment"]["translation"][r].get<double>(), ref["alignment"]["translation"][r].get<double>(),
                1e-6);
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(ours["alignment"]["rotation"][r][k].get<double>(), ref["alignment"]["rotation"][r][k].get<double>(),
                  1e-9);
    }
  }
  expect_stats_equal(ours["ate"], ref["ate"], "ate");
  expect_stats_equal(ours["ate_rot_deg"], ref["ate_rot_deg"], "ate_rot_deg");
  expect_stats_equal(ours["rpe"]["trans"], ref["rpe"]["trans"], "rpe.trans");
  expect_stats_equal(ours["rpe"]["rot_deg"], ref["rpe"]["rot_deg"], "rpe.rot_deg");
}

INSTANTIATE_TEST_SUITE_P(
    Options, EvalEqualsEvoReference,
    ::testing::Values(Case{"defaults", ""}, Case{"se3", "--align se3"}, Case{"sim3", "--align sim3", false, 1.3},
                      Case{"est_longer", "--align se3 --max-dt 0.005", true},
                      Case{"offset", "--align se3 --offset 0.004 --max-dt 0.02"},
                      Case{"delta5", "--align se3 --delta 5"}, Case{"delta5_all", "--align se3 --delta 5 --all-pairs"},
                      Case{"metres", "--align sim3 --delta 2 --delta-unit m", false, 0.8}),
    [](const auto& info) { return info.param.name; });

TEST(Eval, OnLogChannelsRecoversTheOdometryScaleError) {
  const std::string log = std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm";
  std::string out;
  ASSERT_EQ(test::run(kDriftlab + " eval --gt " + log + ":GROUND_TRUTH --est " + log + ":ODOM --align sim3 --json -",
                      &out),
            0);
  const auto j = nlohmann::json::parse(out);
  EXPECT_EQ(j["matched"], 51);
  // The sample's odometry overstates distances by 1%.
  EXPECT_NEAR(j["alignment"]["scale"].get<double>(), 1 / 1.01, 1e-9);
  EXPECT_LT(j["ate"]["max"].get<double>(), 1e-9);
  EXPECT_GT(j["drift"]["count"].get<int>(), 0);
}

TEST(Eval, NothingMatchingExplainsWhyInOneLine) {
  const std::string log = std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm";
  test::TempDir dir;
  std::string out;
  const int code = test::run(kDriftlab + " eval --gt " + log + ":GROUND_TRUTH --est " + log +
                                 ":ODOM --offset 30 2>" + dir.file("err"),
                             &out);
  EXPECT_EQ(code, 2);
  const auto err = test::read_file(dir.file("err"));
  const std::string text(err.begin(), err.end());
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 1) << text;
  EXPECT_NE(text.find("do not overlap"), std::string::npos) << text;
  EXPECT_NE(text.find("--offset 0.000000"), std::string::npos) << text;
}

TEST(Eval, BadInputExitsWithCode2) {
  const std::string log = std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm";
  EXPECT_EQ(test::run(kDriftlab + " eval --gt /nonexistent.tum --est " + log + ":ODOM 2>/dev/null"), 2);
  EXPECT_EQ(test::run(kDriftlab + " eval --gt " + log + ":GROUND_TRUTH --est " + log + ":IMU 2>/dev/null"), 2);
  EXPECT_EQ(test::run(kDriftlab + " eval --gt " + log + ":GROUND_TRUTH --est " + log + ":ODOM --align bogus 2>/dev/null"), 2);
  EXPECT_EQ(test::run(kDriftlab + " eval --gt " + log + ":GROUND_TRUTH --est " + log + ":ODOM --delta 1.5 2>/dev/null"), 2);
}

}  // namespace
}  // namespace driftlab
