// The evaluation `driftlab eval` runs, called as a library (analyzers/evaluate.h): evo's own numbers on real TUM
// RGB-D trajectories (../shared/data/evo/expected.json), the inputs' stamps checked (frozen stamps refused, sorted
// ones said in a note), and bad input refused with one line and ErrorCode::kBadInput. tests/apps/eval_test.cc tests
// the command's options, text and exit codes on top of it.
#include "analyzers/evaluate.h"
#include "analyzers/evaluate_text.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>

#include "tests/test_util.h"

namespace driftlab::analyzers {
namespace {

std::string evo_data(const std::string& name) { return test::shared_data("evo/" + name); }

DeltaUnit unit_of(const std::string& name) {
  return name == "m"     ? DeltaUnit::kMeters
         : name == "deg" ? DeltaUnit::kDegrees
         : name == "rad" ? DeltaUnit::kRadians
                         : DeltaUnit::kFrames;
}

// Every case evo itself computed on the TUM RGB-D trajectories: APE with each alignment, RPE in frames, metres,
// degrees and radians, consecutive and all pairs, pairs from the estimate (evo's default) and from the reference.
// Pair and pose counts must be equal; the statistics to 1e-6 relative. driftlab composes rotations as quaternions
// where evo multiplies 4x4 matrices and takes angles with scipy, and sums in another order: on these files the two
// agree to 2e-12 relative at worst, so 1e-6 leaves room for another compiler or libm while one pair more or less,
// or a pair chosen differently, moves a statistic of these 11 to 32,000 pairs by far more.
TEST(EvaluateEqualsEvo, OnEveryCaseEvoComputedOnRealTrajectories) {
  const std::string expected = evo_data("expected.json");
  if (expected.empty()) return;
  const std::string folder = expected.substr(0, expected.rfind('/'));
  std::ifstream in(expected);
  const auto cases = nlohmann::json::parse(in)["cases"];
  ASSERT_EQ(cases.size(), 81u);
  int checked = 0;
  for (const auto& c : cases) {
    EvaluateOptions o;
    o.gt = folder + "/" + c["gt"].get<std::string>();
    o.est = folder + "/" + c["est"].get<std::string>();
    o.max_dt = c["max_dt"].get<double>();
    const bool ape = c["metric"] == "ape";
    if (ape) {
      const std::string align = c["align"];
      o.align = align == "se3" ? AlignmentType::kSe3 : align == "sim3" ? AlignmentType::kSim3 : AlignmentType::kNone;
    } else {  // evo's RPE is on the unaligned estimate
      o.rpe.delta = c["delta"].get<double>();
      o.rpe.unit = unit_of(c["delta_unit"]);
      o.rpe.delta_tol = c["rel_delta_tol"].get<double>();
      o.rpe.all_pairs = c["all_pairs"].get<bool>();
      o.rpe.pairs_from_reference = c["pairs_from_reference"].get<bool>();
    }
    SCOPED_TRACE(c.dump());
    auto ev = evaluate(o);
    ASSERT_TRUE(ev.ok()) << ev.error().message;
    if (ape) {
      EXPECT_EQ(ev->matched.ref.size(), c["matched"].get<size_t>());
    } else {
      EXPECT_EQ(ev->rpe.pairs.size(), c["pairs"].get<size_t>());
    }
    for (const char* group : {"trans", "rot_deg"}) {
      const bool trans = group == std::string("trans");
      const Stats& ours = ape ? (trans ? ev->ape.trans : ev->ape.rot_deg) : (trans ? ev->rpe.trans : ev->rpe.rot_deg);
      const nlohmann::json got = to_json(ours);
      for (const auto& [key, value] : c[group].items()) {
        const double want = value.get<double>();
        EXPECT_NEAR(got[key].get<double>(), want, 1e-6 * std::abs(want)) << group << "." << key;
      }
    }
    ++checked;
  }
  EXPECT_EQ(checked, 81);
}

/// A trajectory of `n` poses along a circle, 10 Hz from `t0`, with stamp(i) giving each its stamp.
Trajectory circle(size_t n, const std::function<double(size_t)>& stamp) {
  Trajectory t;
  for (size_t i = 0; i < n; ++i) {
    const double a = 0.05 * static_cast<double>(i);
    t.push_back(stamp(i), Eigen::Vector3d(std::cos(a), std::sin(a), 0),
                Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ())));
  }
  return t;
}

// A trajectory whose stamps mostly repeat (a stamp set once) leaves nothing to match in time: refused as bad input,
// naming the input as the user gave it; half of the stamps repeated is the line (more than half is refused), so that
// a camera that repeats every other frame's stamp is still evaluated.
TEST(Evaluate, FrozenStampsAreBadInputAndRepeatedOnesANote) {
  test::TempDir dir;
  ASSERT_TRUE(write_tum(dir.file("gt.tum"), circle(200, [](size_t i) { return 100 + 0.1 * i; })).ok());
  ASSERT_TRUE(
      write_tum(dir.file("frozen.tum"), circle(200, [](size_t i) { return i < 2 ? 100 + 0.1 * i : 100.1; })).ok());
  ASSERT_TRUE(write_tum(dir.file("halves.tum"),
                        circle(200, [](size_t i) { return 100 + 0.1 * static_cast<double>(i - i % 2); }))
                  .ok());
  EvaluateOptions o;
  o.gt = dir.file("gt.tum");
  o.est = dir.file("frozen.tum");
  o.est_name = "EST";
  auto frozen = evaluate(o);
  ASSERT_FALSE(frozen.ok());
  EXPECT_EQ(frozen.error().code, ErrorCode::kBadInput);
  EXPECT_NE(frozen.error().message.find("--est EST: 198 of 200 poses carry the stamp of the pose before them"),
            std::string::npos)
      << frozen.error().message;
  o.est = dir.file("halves.tum");
  o.est_name.clear();
  auto halves = evaluate(o);
  ASSERT_TRUE(halves.ok()) << halves.error().message;
  ASSERT_EQ(halves->notes.size(), 1u);
  EXPECT_NE(halves->notes[0].find("100 poses share their stamp with the pose before them"), std::string::npos)
      << halves->notes[0];
  EXPECT_EQ(halves->matched.ref.size(), 200u);  // each estimated pose has a reference pose at its stamp
  EXPECT_EQ(to_json(*halves)["notes"], nlohmann::json(halves->notes));
}

// Without a reference, the relation error alone: the JSON holds the estimate, the relations and the notes, and no
// matching; a relations file none of whose stamps the estimate has is refused rather than scored over nothing.
TEST(Evaluate, RelationsAloneAndRelationsThatMissTheEstimate) {
  test::TempDir dir;
  ASSERT_TRUE(write_tum(dir.file("est.tum"), circle(200, [](size_t i) { return 100 + 0.1 * i; })).ok());
  // Two relations between poses 10 and 20, and 50 and 60 of the circle, exact; one more between stamps it lacks.
  auto relation = [](double t1, double t2, size_t i, size_t j) {
    const double a = 0.05 * static_cast<double>(i), b = 0.05 * static_cast<double>(j);
    const Eigen::Vector2d d =
        Eigen::Rotation2Dd(-a) * Eigen::Vector2d(std::cos(b) - std::cos(a), std::sin(b) - std::sin(a));
    char line[200];
    std::snprintf(line, sizeof(line), "%.6f %.6f %.9f %.9f 0 0 0 %.9f\n", t1, t2, d.x(), d.y(), b - a);
    return std::string(line);
  };
  const std::string text = relation(101, 102, 10, 20) + relation(105, 106, 50, 60);
  test::write_file(dir.file("rel.txt"), {text.begin(), text.end()});
  EvaluateOptions o;
  o.est = dir.file("est.tum");
  o.relations = dir.file("rel.txt");
  auto ev = evaluate(o);
  ASSERT_TRUE(ev.ok()) << ev.error().message;
  ASSERT_TRUE(ev->relations.has_value());
  EXPECT_EQ(ev->relations->used, 2u);
  EXPECT_LT(ev->relations->trans_m.max, 1e-6);
  const nlohmann::json j = to_json(*ev);
  EXPECT_FALSE(j.contains("matching"));
  EXPECT_EQ(j["relations"]["used"], 2);
  // No reference, no ATE: the demo's headline reader says so in one line instead of reading a zero.
  auto headline = evaluation_headline(j);
  ASSERT_FALSE(headline);
  EXPECT_NE(headline.error().message.find("not an evaluation against a reference"), std::string::npos);
  EXPECT_EQ(j["estimate"]["poses"], 200);

  const std::string elsewhere = relation(500, 501, 10, 20);
  test::write_file(dir.file("elsewhere.txt"), {elsewhere.begin(), elsewhere.end()});
  o.relations = dir.file("elsewhere.txt");
  auto missed = evaluate(o);
  ASSERT_FALSE(missed.ok());
  EXPECT_EQ(missed.error().code, ErrorCode::kBadInput);
  EXPECT_NE(missed.error().message.find("no relation has estimate poses at both of its stamps"), std::string::npos)
      << missed.error().message;
}

// The headline the demo prints, read back from the JSON: an estimate 5 cm off the reference everywhere has an ATE
// of 5 cm (no alignment), RMSE and maximum alike, and no relative error.
TEST(Evaluate, TheHeadlineReadBackFromTheJson) {
  test::TempDir dir;
  Trajectory shifted = circle(100, [](size_t i) { return 10 + 0.1 * i; });
  for (size_t i = 0; i < shifted.size(); ++i) shifted.positions[i].x() += 0.05;
  ASSERT_TRUE(write_tum(dir.file("gt.tum"), circle(100, [](size_t i) { return 10 + 0.1 * i; })).ok());
  ASSERT_TRUE(write_tum(dir.file("est.tum"), shifted).ok());
  EvaluateOptions o;
  o.gt = dir.file("gt.tum");
  o.est = dir.file("est.tum");
  auto ev = evaluate(o);
  ASSERT_TRUE(ev.ok()) << ev.error().message;
  auto h = evaluation_headline(to_json(*ev));
  ASSERT_TRUE(h) << h.error().message;
  EXPECT_EQ(h->matched, 100u);
  EXPECT_NEAR(h->ate_rmse, 0.05, 1e-9);
  EXPECT_NEAR(h->ate_max, 0.05, 1e-9);
  EXPECT_NEAR(h->rpe_rmse, 0, 1e-9);
  // The text `driftlab eval` prints: the matching, then the ATE row (rmse, mean, median, std, min, max).
  const std::string text = evaluation_text(*ev);
  EXPECT_EQ(text.rfind("matched 100 of 100 estimated poses with 100 reference poses (nearest stamp", 0), 0u) << text;
  EXPECT_NE(text.find("ATE [m]            0.050000   0.050000   0.050000   0.000000   0.050000   0.050000\n"),
            std::string::npos)
      << text;
}

}  // namespace
}  // namespace driftlab::analyzers
