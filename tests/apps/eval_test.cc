// End-to-end tests of `driftlab eval`: its numbers equal the evo-semantics reference (tests/analyzers/evo_reference.py,
// numpy, itself held to evo's own numbers) on synthetic trajectories in every mode (evo's own numbers on real ones
// are tests/analyzers/evaluate_test.cc, through the library); the formats evo reads, --offset auto, log channels,
// and bad input refused with exit code 2.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <random>
#include <vector>

#include "analyzers/trajectory.h"
#include "analyzers/trajectory_io.h"
#include "core/log_writer.h"
#include "driftlab/pose_t.hpp"
#include "driftlab/trajectory_setpoint_t.hpp"
#include "tests/doc_figures.h"
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
  ASSERT_EQ(ours.is_null(), ref.is_null()) << what;
  if (ref.is_null()) return;
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
  ASSERT_EQ(test::run(kDriftlab + " eval --gt " + dir.file("gt.tum") + " --est " + dir.file("est.tum") + " " + c.args +
                          " --json",
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

std::string evo_data(const std::string& name) { return test::shared_data("evo/" + name); }

/// A TUM file with every stamp moved by shift [s].
void write_shifted(const std::string& in, const std::string& out, double shift) {
  auto t = analyzers::load_tum(in);
  ASSERT_TRUE(t.ok()) << t.error().message;
  for (auto& s : t->stamps) s += shift;
  ASSERT_TRUE(analyzers::write_tum(out, *t).ok());
}

// --offset auto on real trajectories: the estimates as published, and copies of them stamped by a clock 0.35 s
// behind and on a time base a million seconds off (evo issue 417's case: no stamp matches at all).
TEST(EvalOffsetAuto, FindsTheShiftOfARealTrajectoryAndNoneWhereThereIsNone) {
  const std::pair<const char*, const char*> pairs[] = {{"freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-rgbdslam.txt"},
                                                       {"fr2_desk_groundtruth.txt", "fr2_desk_ORB.txt"},
                                                       {"fr2_desk_groundtruth.txt", "fr2_desk_ORB_kf_mono.txt"}};
  std::vector<double> found_ms, confidence;  // each pair's, as published
  for (const auto& [gt_name, est_name] : pairs) {
    SCOPED_TRACE(est_name);
    const std::string gt = evo_data(gt_name), est = evo_data(est_name);
    if (gt.empty() || est.empty()) return;
    auto offset_of = [&](const std::string& file) {
      std::string out;
      EXPECT_EQ(
          test::run(kDriftlab + " eval --gt " + gt + " --est " + file + " --offset auto --json 2>/dev/null", &out), 0);
      return nlohmann::json::parse(out)["matching"];
    };
    const auto as_published = offset_of(est);
    const double found = as_published["offset"].get<double>();
    // The published estimates are stamped by the camera's clock, which the benchmark synchronised with the motion
    // capture: what is found is small, a fraction of the camera's 33 ms frame (the evaluator's --max-dt is 10 ms).
    EXPECT_LT(std::abs(found), 0.015);
    EXPECT_GE(as_published["offset_auto"]["confidence"].get<double>(), 0.9);
    found_ms.push_back(found * 1e3);
    confidence.push_back(as_published["offset_auto"]["confidence"].get<double>());
    test::TempDir dir;
    for (const double shift : {0.35, 1e6}) {
      ASSERT_NO_FATAL_FAILURE(write_shifted(est, dir.file("shifted.txt"), shift));
      const auto shifted = offset_of(dir.file("shifted.txt"));
      // The same motion, stamped later: the offset found moves by the shift, to the microsecond stamps' rounding.
      EXPECT_NEAR(shifted["offset"].get<double>(), found - shift, 1e-4);
    }
  }
  // docs/trajectory-evaluation.md says what it finds on each (the other figures of the sentence are names: fr1, fr2,
  // ORB-SLAM2).
  test::expect_doc_text_figures(
      "docs/trajectory-evaluation.md", "RGB-D trajectories it finds ", ", and the same motion restamped",
      {found_ms[0], NAN, found_ms[1], NAN, NAN, found_ms[2], NAN, confidence[0], confidence[1], confidence[2]});
}

// KITTI (with and without its times file) and EuRoC files of a real trajectory give what its TUM file gives.
TEST(EvalFormats, KittiAndEurocFilesOfARealTrajectoryEqualItsTumFile) {
  const std::string gt = evo_data("freiburg1_xyz-groundtruth.txt"), est = evo_data("freiburg1_xyz-rgbdslam.txt");
  if (gt.empty() || est.empty()) return;
  test::TempDir dir;
  auto g = analyzers::load_tum(gt);
  auto e = analyzers::load_tum(est);
  ASSERT_TRUE(g.ok() && e.ok());
  auto write = [&](const std::string& name, const std::string& text) {
    test::write_file(dir.file(name), {text.begin(), text.end()});
    return dir.file(name);
  };
  // EuRoC ground truth: nanosecond stamps, w x y z.
  std::string euroc = "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []\n";
  char line[512];
  for (size_t i = 0; i < g->size(); ++i) {
    const auto& p = g->positions[i];
    const auto& q = g->orientations[i];
    std::snprintf(line, sizeof(line), "%lld,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n",
                  static_cast<long long>(std::llround(g->stamps[i] * 1e6)) * 1000, p.x(), p.y(), p.z(), q.w(), q.x(),
                  q.y(), q.z());
    euroc += line;
  }
  // KITTI: the estimate's 3x4 matrices, its stamps in a times file.
  std::string kitti, times;
  for (size_t i = 0; i < e->size(); ++i) {
    const Eigen::Matrix3d r = e->orientations[i].normalized().toRotationMatrix();
    const auto& p = e->positions[i];
    std::snprintf(line, sizeof(line), "%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", r(0, 0),
                  r(0, 1), r(0, 2), p.x(), r(1, 0), r(1, 1), r(1, 2), p.y(), r(2, 0), r(2, 1), r(2, 2), p.z());
    kitti += line;
    std::snprintf(line, sizeof(line), "%.6f\n", e->stamps[i]);
    times += line;
  }
  const std::string euroc_file = write("data.csv", euroc), kitti_file = write("poses.txt", kitti);
  const std::string times_file = write("times.txt", times);
  auto eval = [&](const std::string& args) {
    std::string out;
    EXPECT_EQ(
        test::run(kDriftlab + " eval" + args + " --align se3 --delta 0.1 --delta-unit m --json 2>/dev/null", &out), 0)
        << args;
    return nlohmann::json::parse(out.empty() ? "{}" : out);
  };
  const auto tum = eval(" --gt " + gt + " --est " + est);
  const auto other = eval(" --gt " + euroc_file + " --est " + kitti_file + " --est-times " + times_file);
  EXPECT_EQ(other["matched"], tum["matched"]);
  EXPECT_EQ(other["rpe"]["pairs"], tum["rpe"]["pairs"]);
  // Quaternions through rotation matrices and back, stamps through nanoseconds: equal to rounding.
  for (const char* k : {"rmse", "max"}) {
    EXPECT_NEAR(other["ate"][k].get<double>(), tum["ate"][k].get<double>(), 1e-9);
    EXPECT_NEAR(other["ate_rot_deg"][k].get<double>(), tum["ate_rot_deg"][k].get<double>(), 1e-7);
    EXPECT_NEAR(other["rpe"]["trans"][k].get<double>(), tum["rpe"]["trans"][k].get<double>(), 1e-9);
  }
  // KITTI without times: pose for pose, against another trajectory without stamps of the same length only.
  const auto same = eval(" --gt " + kitti_file + " --est " + kitti_file);
  EXPECT_EQ(same["matched"].get<size_t>(), e->size());
  EXPECT_EQ(same["matching"]["method"], "index");
  EXPECT_LT(same["ate"]["max"].get<double>(), 1e-12);
  const auto r = test::run_capture(kDriftlab + " eval --gt " + gt + " --est " + kitti_file);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("give --est-times FILE"), std::string::npos) << r.err;
}

INSTANTIATE_TEST_SUITE_P(
    Options, EvalEqualsEvoReference,
    ::testing::Values(Case{"defaults", ""}, Case{"se3", "--align se3"}, Case{"sim3", "--align sim3", false, 1.3},
                      Case{"est_longer", "--align se3 --max-dt 0.005", true},
                      Case{"offset", "--align se3 --offset 0.004 --max-dt 0.02"},
                      Case{"delta5", "--align se3 --delta 5"}, Case{"delta5_all", "--align se3 --delta 5 --all-pairs"},
                      Case{"metres", "--align sim3 --delta 2 --delta-unit m", false, 0.8},
                      Case{"metres_all", "--align sim3 --delta 2 --delta-unit m --all-pairs", false, 0.8},
                      Case{"metres_reference",
                           "--delta 2 --delta-unit m --pairs-from-reference --all-pairs --delta-tol 0.02"},
                      Case{"degrees", "--delta 20 --delta-unit deg"},
                      Case{"degrees_all", "--delta 20 --delta-unit deg --all-pairs --pairs-from-reference"},
                      Case{"radians_all", "--delta 0.5 --delta-unit rad --all-pairs --delta-tol 0.05"},
                      Case{"no_pairs", "--delta 1000 --delta-unit m"}, Case{"origin", "--align origin"},
                      Case{"origin_est_longer", "--align origin --max-dt 0.005 --delta 2 --delta-unit m", true},
                      Case{"origin_offset", "--align origin --offset 0.004 --max-dt 0.02"}),
    [](const auto& info) { return info.param.name; });

TEST(Eval, OnLogChannelsRecoversTheOdometryScaleError) {
  const std::string log = std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm";
  std::string out;
  ASSERT_EQ(
      test::run(kDriftlab + " eval --gt " + log + ":GROUND_TRUTH --est " + log + ":ODOM --align sim3 --json", &out), 0);
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

/// A log with a ground-truth channel GT (a circle at 10 Hz for 50 s) and an estimate EST at the stamps `stamps`
/// (seconds from the start), the pose of each changed by `tamper` (index, pose) when given.
std::string write_pose_log(const test::TempDir& dir, const std::vector<double>& stamps,
                           const std::function<void(size_t, pose_t&)>& tamper = {}) {
  auto w = LogWriter::create(dir.file("poses.lcm"));
  EXPECT_TRUE(w.ok());
  auto pose_at = [](double s) {
    pose_t p{};
    p.header.utime = static_cast<int64_t>(std::llround((1700000000.0 + s) * 1e6));
    p.child_frame_id = "base_link";
    p.position = {std::cos(0.2 * s), std::sin(0.2 * s), 0};
    p.orientation = {std::cos(0.1 * s + M_PI / 4), 0, 0, std::sin(0.1 * s + M_PI / 4)};
    return p;
  };
  int64_t seq = 0;
  for (int i = 0; i <= 500; ++i) {
    pose_t p = pose_at(0.1 * i);
    p.header.seq = seq++;
    EXPECT_TRUE(w->write(p.header.utime, "GT", test::encode(p)).ok());
  }
  for (size_t i = 0; i < stamps.size(); ++i) {
    pose_t p = pose_at(stamps[i]);
    p.header.seq = static_cast<int64_t>(i);
    if (tamper) tamper(i, p);
    EXPECT_TRUE(w->write(p.header.utime, "EST", test::encode(p)).ok());
  }
  EXPECT_TRUE(w->close().ok());
  return dir.file("poses.lcm");
}

std::vector<double> every(double period, int n) {
  std::vector<double> v;
  for (int i = 0; i < n; ++i) v.push_back(period * i);
  return v;
}

// Hostile inputs of the issue, each refused with one line and exit code 2 where it used to give a number: a zero
// quaternion in a log scored 0 degrees, NaN and infinite poses gave "nan", and 500 estimates on one stamp gave
// "matched 500 of 500, scale 0".
TEST(EvalBadPoses, FromALogAreRefusedAsFromATumFile) {
  struct Bad {
    const char* what;
    std::function<void(size_t, pose_t&)> tamper;
    const char* message;
  };
  const Bad cases[] = {
      {"zero quaternion", [](size_t i, pose_t& p) { if (i == 7) p.orientation = {0, 0, 0, 0}; }, "the quaternion is zero"},
      {"half quaternion", [](size_t i, pose_t& p) { if (i == 7) p.orientation = {0.5, 0, 0, 0}; }, "norm is 0.5, not 1"},
      {"NaN position", [](size_t i, pose_t& p) { if (i == 7) p.position.y = NAN; }, "a number is not finite"},
      {"infinite position", [](size_t i, pose_t& p) { if (i == 7) p.position.x = INFINITY; }, "a number is not finite"},
      {"NaN quaternion", [](size_t i, pose_t& p) { if (i == 7) p.orientation.z = NAN; }, "a number is not finite"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.what);
    test::TempDir dir;
    const std::string log = write_pose_log(dir, every(0.2, 100), c.tamper);
    const auto r = test::run_capture(kDriftlab + " eval --gt " + log + ":GT --est " + log + ":EST --align sim3");
    EXPECT_EQ(r.code, 2);
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(" on EST: "), std::string::npos) << r.err;  // the log, the byte and the channel
    EXPECT_NE(r.err.find(c.message), std::string::npos) << r.err;
    EXPECT_EQ(r.out, "");
  }
}

TEST(EvalBadPoses, FrozenStampsAreRefused) {
  test::TempDir dir;
  // 500 estimates of a moving robot, all stamped with the first one's stamp.
  const std::string log = write_pose_log(dir, every(0.1, 500), [](size_t, pose_t& p) {
    p.header.utime = 1700000000 * int64_t{1000000};
  });
  const auto r = test::run_capture(kDriftlab + " eval --gt " + log + ":GT --est " + log + ":EST --align sim3");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("499 of 500 poses carry the stamp of the pose before them"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("frozen stamps"), std::string::npos) << r.err;
}

TEST(EvalBadPoses, OutOfOrderStampsAreSortedAndSaidSo) {
  // The same estimate written in order and with two pairs of lines swapped (three poses then come after a later
  // one): the same numbers, and a note.
  const std::string gt = evo_data("freiburg1_xyz-groundtruth.txt"), est = evo_data("freiburg1_xyz-rgbdslam.txt");
  if (gt.empty() || est.empty()) return;
  test::TempDir dir;
  std::ifstream in(est);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) {
    if (!l.empty() && l[0] != '#') lines.push_back(l);
  }
  std::swap(lines[100], lines[101]);
  std::swap(lines[400], lines[450]);
  std::string text;
  for (const auto& l : lines) text += l + "\n";
  test::write_file(dir.file("shuffled.txt"), {text.begin(), text.end()});
  const std::string args = " --align se3 --delta 0.1 --delta-unit m --json";
  std::string sorted_out;
  ASSERT_EQ(test::run(kDriftlab + " eval --gt " + gt + " --est " + est + args + " 2>/dev/null", &sorted_out), 0);
  const auto r = test::run_capture(kDriftlab + " eval --gt " + gt + " --est " + dir.file("shuffled.txt") + args);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("note: --est " + dir.file("shuffled.txt") + ": 3 poses were stamped earlier than the pose before"),
            std::string::npos)
      << r.err;
  const auto a = nlohmann::json::parse(sorted_out), b = nlohmann::json::parse(r.out);
  EXPECT_EQ(b["rpe"]["pairs"], a["rpe"]["pairs"]);
  EXPECT_EQ(b["rpe"]["trans"], a["rpe"]["trans"]);
  EXPECT_EQ(b["ate"], a["ate"]);
  EXPECT_EQ(b["notes"].size(), 1u);
}

TEST(EvalBadPoses, AnRpeOverNoPairsSaysSoInsteadOfZero) {
  test::TempDir dir;
  const std::string log = write_pose_log(dir, every(0.2, 100));
  const auto r = test::run_capture(kDriftlab + " eval --gt " + log + ":GT --est " + log + ":EST --delta 100 --delta-unit m");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("RPE: no pair of poses is 100 m apart along the estimate: try a smaller --delta"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(r.out.find("RPE [m]"), std::string::npos) << r.out;
  std::string json;
  ASSERT_EQ(
      test::run(kDriftlab + " eval --gt " + log + ":GT --est " + log + ":EST --delta 100 --delta-unit m --json", &json),
      0);
  const auto j = nlohmann::json::parse(json);
  EXPECT_EQ(j["rpe"]["pairs"], 0);
  EXPECT_TRUE(j["rpe"]["trans"].is_null());
  EXPECT_TRUE(j["rpe"]["rot_deg"].is_null());
}

TEST(EvalBadPoses, AnAlignmentOfPointsOnALineIsRefused) {
  test::TempDir dir;
  // The estimate stands still: its positions are one point, which no se3 or sim3 alignment can be fitted to.
  const std::string log = write_pose_log(dir, every(0.2, 100), [](size_t, pose_t& p) { p.position = {1, 2, 3}; });
  for (const char* type : {"se3", "sim3"}) {
    const auto r = test::run_capture(kDriftlab + " eval --gt " + log + ":GT --est " + log + ":EST --align " + type);
    EXPECT_EQ(r.code, 2) << type;
    EXPECT_NE(r.err.find(std::string("--align ") + type), std::string::npos) << r.err;
  }
  // posyaw moves the still estimate to the reference's mean whatever the yaw: a frozen estimator gets its error
  // (every yaw gives the same position error), not a refusal.
  const auto r = test::run_capture(kDriftlab + " eval --gt " + log + ":GT --est " + log + ":EST --align posyaw");
  EXPECT_EQ(r.code, 0) << r.err;
}

/// A drone's log: its ground truth GROUND_TRUTH at 100 Hz (`truth` gives the pose at a time) and the setpoints it
/// was given on SETPOINT at 20 Hz along a climbing, turning path, with `yaw_bias` added to their heading.
std::string write_drone_log(const test::TempDir& dir, const std::function<Eigen::Isometry3d(double)>& truth,
                            double yaw_bias) {
  auto w = LogWriter::create(dir.file("drone.lcm"));
  EXPECT_TRUE(w.ok());
  const int64_t t0 = 1763776800000000;
  for (int64_t i = 0; i <= 3000; ++i) {
    const double t = 0.01 * static_cast<double>(i);
    const Eigen::Isometry3d x = truth(t);
    const Eigen::Quaterniond q(x.rotation());
    pose_t p{};
    p.header = {i, t0 + 10000 * i, "world"};
    p.child_frame_id = "base_link";
    p.position = {x.translation().x(), x.translation().y(), x.translation().z()};
    p.orientation = {q.w(), q.x(), q.y(), q.z()};
    EXPECT_TRUE(w->write(p.header.utime, "GROUND_TRUTH", test::encode(p)).ok());
    if (i % 5 != 0) continue;
    driftlab::trajectory_setpoint_t sp{};
    sp.header = {i / 5, t0 + 10000 * i, "odom"};
    sp.position = {2 * std::cos(0.3 * t), 2 * std::sin(0.3 * t), 1 + 0.05 * t};
    sp.yaw = 0.3 * t + M_PI / 2 + yaw_bias;
    EXPECT_TRUE(w->write(sp.header.utime, "SETPOINT", test::encode(sp)).ok());
  }
  EXPECT_TRUE(w->close().ok());
  return dir.file("drone.lcm");
}

/// The pose a setpoint of write_drone_log asks for at t (without its yaw bias), in `frame`.
Eigen::Isometry3d setpoint_pose(double t, const Eigen::Isometry3d& frame = Eigen::Isometry3d::Identity()) {
  Eigen::Isometry3d x = Eigen::Isometry3d::Identity();
  x.translation() = Eigen::Vector3d(2 * std::cos(0.3 * t), 2 * std::sin(0.3 * t), 1 + 0.05 * t);
  x.linear() = Eigen::AngleAxisd(0.3 * t + M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return frame * x;
}

// The drone's setpoint tracking: a setpoint channel read as the poses it asks for (position, level, turned by its
// yaw), scored against ground truth like any estimate. The vehicle flies 8 cm off each setpoint, and each setpoint's
// heading is 0.05 rad off the vehicle's: those are the errors, to rounding.
TEST(EvalSetpoints, ASetpointChannelIsTheTrajectoryItAsksFor) {
  test::TempDir dir;
  const Eigen::Vector3d off(0.06, 0.0, -0.0529150262212918);  // 8 cm
  const std::string log = write_drone_log(
      dir,
      [&](double t) {
        Eigen::Isometry3d x = setpoint_pose(t);
        x.translation() += off;
        return x;
      },
      0.05);
  std::string out;
  ASSERT_EQ(test::run(kDriftlab + " eval --gt " + log + ":GROUND_TRUTH --est " + log + ":SETPOINT --json", &out), 0);
  const auto j = nlohmann::json::parse(out);
  EXPECT_EQ(j["matched"], 601);
  EXPECT_NEAR(j["ate"]["rmse"].get<double>(), off.norm(), 1e-9);
  EXPECT_NEAR(j["ate"]["max"].get<double>(), off.norm(), 1e-9);
  EXPECT_NEAR(j["ate_rot_deg"]["max"].get<double>(), 0.05 * 180 / M_PI, 1e-6);
  EXPECT_NEAR(j["ate_rot_deg"]["min"].get<double>(), 0.05 * 180 / M_PI, 1e-6);
  // A setpoint whose heading is not finite is refused like any pose: one line naming the log, byte and channel.
  test::TempDir nan_dir;
  const std::string nan_log = write_drone_log(
      nan_dir, [](double t) { return setpoint_pose(t); }, NAN);
  const auto bad =
      test::run_capture(kDriftlab + " eval --gt " + nan_log + ":GROUND_TRUTH --est " + nan_log + ":SETPOINT");
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find(" on SETPOINT: a number is not finite"), std::string::npos) << bad.err;
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
}

// --align origin (evo's --align_origin): a ground truth in another frame than the setpoints (rotated 0.4 rad about
// a tilted axis and moved), otherwise the same motion: moved so its first matched pose is the reference's, the
// estimate is the reference, and the alignment is that frame's motion; without it, metres off.
TEST(EvalAlignOrigin, TakesTheFirstMatchedPoseOntoTheReferences) {
  test::TempDir dir;
  Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
  frame.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.1, -0.2, 1).normalized()).toRotationMatrix();
  frame.translation() = Eigen::Vector3d(2.0, -1.0, 0.5);
  const std::string log = write_drone_log(
      dir, [&](double t) { return setpoint_pose(t, frame); }, 0.0);
  std::string out;
  const std::string args = " eval --gt " + log + ":GROUND_TRUTH --est " + log + ":SETPOINT --json";
  ASSERT_EQ(test::run(kDriftlab + args + " --align origin", &out), 0);
  const auto j = nlohmann::json::parse(out);
  EXPECT_EQ(j["alignment"]["type"], "origin");
  EXPECT_EQ(j["alignment"]["scale"], 1.0);
  EXPECT_LT(j["ate"]["max"].get<double>(), 1e-9);
  EXPECT_LT(j["ate_rot_deg"]["max"].get<double>(), 1e-6);
  for (int r = 0; r < 3; ++r) {
    EXPECT_NEAR(j["alignment"]["translation"][r].get<double>(), frame.translation()[r], 1e-9);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(j["alignment"]["rotation"][r][c].get<double>(), frame.linear()(r, c), 1e-9);
  }
  ASSERT_EQ(test::run(kDriftlab + args, &out), 0);
  EXPECT_GT(nlohmann::json::parse(out)["ate"]["rmse"].get<double>(), 1.0);
}

TEST(Eval, BadInputExitsWithCode2) {
  const std::string log = std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm";
  EXPECT_EQ(test::run(kDriftlab + " eval --gt /nonexistent.tum --est " + log + ":ODOM 2>/dev/null"), 2);
  EXPECT_EQ(test::run(kDriftlab + " eval --gt " + log + ":GROUND_TRUTH --est " + log + ":IMU 2>/dev/null"), 2);
  EXPECT_EQ(test::run(kDriftlab + " eval --gt " + log + ":GROUND_TRUTH --est " + log + ":ODOM --align bogus 2>/dev/null"), 2);
  EXPECT_EQ(test::run(kDriftlab + " eval --gt " + log + ":GROUND_TRUTH --est " + log + ":ODOM --delta 1.5 2>/dev/null"), 2);
  EXPECT_EQ(test::run(kDriftlab + " eval --gt " + log + ":GROUND_TRUTH --est " + log +
                      ":ODOM --delta 200 --delta-unit deg 2>/dev/null"),
            2);
  EXPECT_EQ(test::run(kDriftlab + " eval --gt " + log + ":GROUND_TRUTH --est " + log + ":ODOM --offset soon 2>/dev/null"), 2);
  EXPECT_EQ(test::run(kDriftlab + " eval --est " + log + ":ODOM 2>/dev/null"), 2);
}

}  // namespace
}  // namespace driftlab
