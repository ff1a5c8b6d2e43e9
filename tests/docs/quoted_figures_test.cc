// Figures a page quotes from another page, where that other page is the one kept up to date: timings measured by
// scripts/bench live in docs/benchmarks.md (never asserted in a timed test), so the README's speed claims and the
// pages that repeat them are held to it; docs/simulator.md's drone figures to the tutorial whose blocks run; and
// docs/slam.md's robustness count to the table that tests check row by row. When the page quoted moves a figure (a
// benchmark run again, a tutorial regenerated), the quoting page fails here until it says the same.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include "tests/doc_figures.h"

namespace driftlab {
namespace {

/// The numbers of `text` as values.
std::vector<double> values_of(const std::string& text) {
  std::vector<double> values;
  for (const std::string& printed : test::printed_numbers(text)) values.push_back(test::printed_value(printed));
  return values;
}

/// The numbers of a cell of a table row (test::doc_table_row); fails the test when the row or column is not there.
std::vector<double> cell_numbers(const std::string& page, const std::string& after, const std::string& label,
                                 size_t column) {
  const auto row = test::doc_table_row(page, after, label);
  EXPECT_GT(row.size(), column) << page << ", the table after \"" << after << "\": no row \"" << label
                                << "\" with a column " << column;
  return row.size() > column ? values_of(row[column]) : std::vector<double>{};
}

/// The numbers of a stretch of prose (test::doc_text_between); fails the test when it is not there.
std::vector<double> text_numbers(const std::string& page, const std::string& from, const std::string& to) {
  const std::string text = test::doc_text_between(page, from, to);
  EXPECT_FALSE(text.empty()) << page << ": no text from \"" << from << "\" to \"" << to << "\"";
  return values_of(text);
}

const char* const kBenchmarks = "docs/benchmarks.md";
const char* const kMeasured = "docs/benchmarks.md (scripts/bench)";

// The simulator's speed: the README says the slowest of the three runs of the default scenario, as the target does.
TEST(QuotedFigures, TheReadmeSaysTheSimulatorsRealTimeFactor) {
  const auto runs = cell_numbers(kBenchmarks, "## Simulator", "indoor (default)", 1);
  ASSERT_EQ(runs.size(), 3u) << "docs/benchmarks.md's simulator table: three runs of the default scenario";
  test::expect_doc_text_figures("README.md", "written to a log with the fault manifest; ", "x real time on one core",
                                {*std::min_element(runs.begin(), runs.end())}, kMeasured);
}

// Trajectory evaluation: the README's "over N times faster" is against evo's own time (the benchmark's second
// ratio; its first is against the slower numpy reference), so N must not exceed it.
TEST(QuotedFigures, TheReadmeSaysHowMuchFasterThanEvo) {
  const auto ratios = cell_numbers(kBenchmarks, "## Trajectory evaluation", "100,000", 3);
  ASSERT_EQ(ratios.size(), 3u) << "docs/benchmarks.md's eval table: \"NNNx (about NNNx against evo's reported N s)\"";
  const auto claim = text_numbers("README.md", "with evo's numbers (to 1e-6) over ", " times faster");
  ASSERT_EQ(claim.size(), 1u);
  EXPECT_LE(claim[0], ratios[1]) << "README.md says over " << claim[0] << " times evo's speed; docs/benchmarks.md "
                                 << "measured " << ratios[1] << "x";
}

// The recorder: no loss at 200k msg/s where lcm-logger lost its share (README), and the loss at 100k msg/s and of
// 1 MB messages (docs/recorder.md).
TEST(QuotedFigures, TheRecorderPagesSayTheMeasuredLosses) {
  const auto peer_200k = cell_numbers(kBenchmarks, "## Recorder", "200,000", 2);
  const auto ours_200k = cell_numbers(kBenchmarks, "## Recorder", "200,000", 3);
  ASSERT_EQ(peer_200k.size(), 2u) << "lcm-logger's loss: \"N (P%)\"";
  ASSERT_EQ(ours_200k.size(), 1u);
  EXPECT_EQ(ours_200k[0], 0) << "README.md says driftlab record loses none at 200k msg/s";
  // "none at 200k msg/s here, where `lcm-logger` loses P%": the row's rate in thousands, and its loss.
  test::expect_doc_text_figures("README.md", "without the losses of stock `lcm-logger` (none at ", "%), and writes",
                                {200, peer_200k[1]}, kMeasured);

  const auto peer_100k = cell_numbers(kBenchmarks, "## Recorder", "100,000", 2);
  const auto ours_100k = cell_numbers(kBenchmarks, "## Recorder", "100,000", 3);
  ASSERT_EQ(peer_100k.size(), 2u);
  ASSERT_EQ(ours_100k.size(), 1u);
  const auto large = text_numbers(kBenchmarks, "for 60 s: `lcm-logger` lost ", "%;");
  ASSERT_EQ(large.size(), 3u) << "docs/benchmarks.md: \"lost N of M (P%\" for 1 MB messages";
  const auto ours_large = text_numbers(kBenchmarks, "`driftlab record` lost ", " (15 GB written)");
  ASSERT_EQ(ours_large.size(), 1u);
  EXPECT_EQ(ours_100k[0] + ours_large[0], 0) << "docs/recorder.md says driftlab loses none";
  // "P% of 64-byte messages at 100k msg/s, and P% of 1 MB messages at 250 MB/s": the sizes and rates are the
  // benchmark's conditions, not figures it measures.
  test::expect_doc_text_figures("docs/recorder.md",
                                "the machine carries (`docs/benchmarks.md`: ", ", while driftlab loses none)",
                                {peer_100k[1], NAN, NAN, large[2], NAN, NAN}, kMeasured);
}

// The log reader: docs/architecture.md's "reads Nx faster for small messages" is the benchmark's 100 B read ratio.
TEST(QuotedFigures, TheArchitectureSaysTheReadersSpeedUp) {
  const auto ratio = cell_numbers(kBenchmarks, "## Log I/O", "read 100 B", 3);
  ASSERT_EQ(ratio.size(), 1u);
  test::expect_doc_text_figures("docs/architecture.md", "(`docs/benchmarks.md`: reads ", "x faster for small",
                                {ratio[0]}, kMeasured);
}

// docs/simulator.md's account of the drone with its IMU 110 ms ahead quotes the tutorial that runs it: the share of
// the IMU rejected, how much worse the setpoints are tracked, and the clock offset diagnose finds.
TEST(QuotedFigures, TheSimulatorPageSaysWhatTheDroneTutorialMeasures) {
  const char* const tutorial = "docs/tutorial-why-does-my-drone-ignore-its-imu.md";
  const auto late = cell_numbers(tutorial, "| flight | IMU rejected", "IMU 110 ms ahead, as logged", 1);
  const auto late_tracking = cell_numbers(tutorial, "| flight | IMU rejected", "IMU 110 ms ahead, as logged", 2);
  const auto clean_tracking = cell_numbers(tutorial, "| flight | IMU rejected", "clean (`drone.yaml`)", 2);
  const auto offset = text_numbers(tutorial, "restamp IMU: +", " ms, +0 ppm");
  ASSERT_EQ(late.size(), 1u);
  ASSERT_EQ(late_tracking.size(), 1u);
  ASSERT_EQ(clean_tracking.size(), 1u);
  ASSERT_EQ(offset.size(), 1u);
  test::expect_doc_text_figures("docs/simulator.md", "(PX4 EKF2's rule) and rejects ", " ms ahead; `driftlab replay",
                                {late[0], late_tracking[0] / clean_tracking[0], offset[0]}, tutorial);
}

// The latency arm's delay, as diagnose measures it: docs/replay.md's block prints it when it re-times the run's
// commands; docs/report.md's arm plot moves the measured motion by it, and docs/simulator.md quotes it.
TEST(QuotedFigures, ThePagesSayTheArmsDelayAsTheReplayMeasuresIt) {
  const auto delay = text_numbers("docs/replay.md", "retime ARM_CMD: each command starts ", " ms before it arrived");
  ASSERT_EQ(delay.size(), 1u);
  test::expect_doc_text_figures("docs/report.md", "late, and the measured motion moved ", " ms earlier", {delay[0]},
                                "docs/replay.md");
  test::expect_doc_text_figures("docs/simulator.md", "arrived less the delay diagnose measured (",
                                " ms), on a controller", {delay[0]}, "docs/replay.md");
}

// The SLAM tutorial's table "side by side" is its evaluations' rmse column and drift: each row against the block that
// prints it (the blocks run as the doc test; the table is prose to the runner).
TEST(QuotedFigures, TheSlamDriftTutorialsTableSaysItsBlocks) {
  const std::string page = "docs/tutorial-why-does-my-slam-drift.md";
  const std::pair<const char*, const char*> rows[] = {
      {"wheel odometry (`ODOM`)", "--est clean.lcm:ODOM --align posyaw"},
      {"2D SLAM (`SLAM_POSE`, MRPT ICP)", "--est slam.lcm:SLAM_POSE --align posyaw"}};
  for (const auto& [label, command] : rows) {
    // ATE's six statistics, RPE's six, then the drift in % of distance.
    const auto printed = text_numbers(page, command, " % of distance");
    ASSERT_EQ(printed.size(), 13u) << page << ", the block of " << command;
    const double ate = printed[0], rpe = printed[6], drift = printed[12];
    const std::string source = "its block (" + std::string(command) + ")";
    test::expect_doc_figures(page, "| estimate | ATE |", label, 1, {ate}, source);
    test::expect_doc_figures(page, "| estimate | ATE |", label, 2, {rpe}, source);
    test::expect_doc_figures(page, "| estimate | ATE |", label, 3, {drift}, source);
  }
}

// docs/slam.md's "N of the M runs meet the bar": the sum of the robustness table's counts, each row of which a
// test checks (Intel's and ACES's the tutorial's block, the other four SlamRobustness).
TEST(QuotedFigures, TheRobustnessCountIsTheTablesSum) {
  double met = 0, runs = 0;
  for (const char* log : {"Intel", "ACES", "Freiburg 079", "MIT CSAIL", "Freiburg clinic", "MIT Killian Court"}) {
    const auto count = cell_numbers("docs/slam.md", "### How robust: ten runs of each log", log, 1);
    ASSERT_EQ(count.size(), 2u) << "docs/slam.md's robustness table, " << log << ": \"N of M\"";
    met += count[0], runs += count[1];
  }
  test::expect_doc_text_figures("docs/slam.md", "all ten folded (0.14-2.9 m mean). ", " runs meet the bar", {met, runs},
                                "the robustness table's rows");
}

}  // namespace
}  // namespace driftlab
