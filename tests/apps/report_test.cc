// `driftlab demo` and `driftlab report` end to end: a short run of the default scenario, its faults scored
// against the simulator's manifest, the ATE before and after restamping, and the report rendered in headless
// Chromium with every plot drawn.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>
#include <utility>
#include <vector>

#include "tests/test_util.h"

namespace driftlab {
namespace {

const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";

test::CmdResult driftlab(const std::string& args) { return test::run_capture(kDriftlab + " " + args); }

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

/// The page's body attribute `name` after headless Chromium loaded it and ran its scripts; -1 when absent.
int rendered_attribute(const std::string& page, const std::string& name, std::string* dom_out = nullptr) {
  test::TempDir profile;
  const auto r = test::run_capture(
      "chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run --disable-background-networking "
      "--disable-component-update --disable-sync --user-data-dir=" + profile.path() +
      " --virtual-time-budget=10000 --dump-dom file://" + page + " 2>/dev/null");
  EXPECT_EQ(r.code, 0) << "chromium failed";
  if (dom_out != nullptr) *dom_out = r.out;
  std::smatch m;
  if (!std::regex_search(r.out, m, std::regex(name + "=\"(\\d+)\""))) return -1;
  return std::stoi(m[1]);
}

bool have_chromium() {
  if (std::system("command -v chromium >/dev/null 2>&1") == 0) return true;
  const char* ci = std::getenv("CI");
  EXPECT_FALSE(ci != nullptr && std::string(ci) == "true") << "chromium missing under CI";
  return false;
}

/// Opens a report page in headless Chromium as a person would and checks it: every zoomable chart drawn by dygraphs
/// without a JavaScript error, every PNG decoded with ink, time axes from the log's start (never a date's 1e9 s),
/// and a 1200x3000 screenshot with something on it, kept as DRIFTLAB_SCREENSHOT_DIR/NAME.png to look at.
void check_page(const std::string& page, const std::string& name, int min_charts) {
  std::string dom;
  const int charts = rendered_attribute(page, "data-charts", &dom);
  EXPECT_GE(charts, min_charts) << name;
  EXPECT_EQ(rendered_attribute(page, "data-charts-drawn"), charts) << name;
  EXPECT_NE(dom.find("data-charts-ready=\"1\""), std::string::npos) << name;
  EXPECT_EQ(rendered_attribute(page, "data-js-errors"), 0) << name;
  const int plots = rendered_attribute(page, "data-plots");
  EXPECT_GE(plots, 1) << name;
  EXPECT_EQ(rendered_attribute(page, "data-plots-drawn"), plots) << name;
  // dygraphs is inlined: the page fetches nothing.
  EXPECT_EQ(dom.find("src=\"http"), std::string::npos) << name;
  EXPECT_EQ(dom.find("<script src"), std::string::npos) << name;

  // The charts' data, as the page's script holds it: x in seconds from the start, never 1.7e9.
  std::ifstream in(page);
  const std::string html((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto from = html.find("var specs = "), to = html.find(", colors = ", from);
  ASSERT_NE(from, std::string::npos) << name;
  const auto specs = nlohmann::json::parse(html.substr(from + 12, to - from - 12));
  ASSERT_EQ(static_cast<int>(specs.size()), charts) << name;
  for (const auto& spec : specs) {
    ASSERT_FALSE(spec["data"].empty()) << name;
    EXPECT_GT(spec["data"].front()[0].get<double>(), -1.0) << name << " " << spec["labels"];
    EXPECT_LT(spec["data"].back()[0].get<double>(), 1e5) << name << " " << spec["labels"];
  }
  // Legends are written below each chart (dygraphs' labelsDiv), never over the data.
  for (const auto& spec : specs)
    EXPECT_NE(html.find("id='" + spec["id"].get<std::string>() + "-labels'"), std::string::npos);

  const std::string dir = DRIFTLAB_SCREENSHOT_DIR;
  std::filesystem::create_directories(dir);
  const std::string shot = dir + "/" + name + ".png";
  std::filesystem::remove(shot);
  test::TempDir profile;
  const auto r = test::run_capture(
      "chromium --headless --disable-gpu --no-sandbox --hide-scrollbars --no-first-run --disable-sync "
      "--disable-background-networking --disable-component-update --user-data-dir=" +
      profile.path() + " --virtual-time-budget=10000 --screenshot=" + shot + " --window-size=1200,3000 file://" + page +
      " 2>/dev/null");
  EXPECT_EQ(r.code, 0) << name;
  ASSERT_TRUE(std::filesystem::exists(shot)) << name;
  // A blank 1200x3000 page compresses to a few kilobytes; tables, charts and plots to hundreds.
  EXPECT_GT(std::filesystem::file_size(shot), 60000u) << shot;
}

/// diagnose's headline: the first of its problems ("NAME: reason"), from its text.
std::string diagnose_headline(const std::string& log) {
  const auto r = driftlab("diagnose " + log);
  const std::string mark = "\nproblems:\n  ";
  const auto at = r.out.find(mark);
  if (at == std::string::npos) return "";
  const auto from = at + mark.size();
  return r.out.substr(from, r.out.find('\n', from) - from);
}

/// The text of the page's first summary card, unescaped; empty when the first card is not the headline.
std::string page_headline(const std::string& page) {
  std::ifstream in(page);
  const std::string html((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::smatch m;
  if (!std::regex_search(
          html, m, std::regex("<div class='cards'><div class='card lead[^']*' id='headline'>[^<]*<b>([^<]*)</b>"))) {
    return "";
  }
  std::string text = m[1];
  for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{
           {"&#x27;", "'"}, {"&quot;", "\""}, {"&lt;", "<"}, {"&gt;", ">"}, {"&amp;", "&"}}) {
    for (size_t at; (at = text.find(from)) != std::string::npos;) text.replace(at, from.size(), to);
  }
  return text;
}

class DemoCli : public ::testing::Test {
 protected:
  /// 30 s of the default scenario through the whole demo, once per test process.
  static void SetUpTestSuite() {
    dir_ = new test::TempDir;
    const auto r = driftlab("demo --duration 30 --json -o " + dir_->path());
    ASSERT_EQ(r.code, 0) << r.err;
    summary_ = new nlohmann::json(nlohmann::json::parse(r.out));
  }
  static void TearDownTestSuite() {
    delete summary_;
    delete dir_;
  }
  static std::string file(const std::string& name) { return dir_->file(name); }
  static test::TempDir* dir_;
  static nlohmann::json* summary_;
};
test::TempDir* DemoCli::dir_ = nullptr;
nlohmann::json* DemoCli::summary_ = nullptr;

TEST_F(DemoCli, FindsTheInjectedFaultsAndRestampingLowersTheError) {
  const auto& s = *summary_;
  // The faults the simulator injected, from its manifest (the analyzers never read it).
  const auto manifest = read_json(file("sim.faults.json"));
  double imu_offset = 0;
  int64_t scan_dropped = 0;
  for (const auto& f : manifest["faults"]) {
    if (f["channel"] == "IMU" && f["kind"] == "clock_offset") imu_offset = f["params"]["offset_s"];
    if (f["channel"] == "SCAN" && (f["kind"] == "drop" || f["kind"] == "burst_drop")) {
      scan_dropped += static_cast<int64_t>(f["affected_seq"].size());
    }
  }
  ASSERT_GT(imu_offset, 0);
  ASSERT_GT(scan_dropped, 0);
  EXPECT_EQ(s["worst_stream"]["name"], "IMU");
  EXPECT_NEAR(s["clock_offsets_s"]["IMU"].get<double>(), imu_offset, 0.001);
  EXPECT_EQ(s["drops"]["SCAN"].get<int64_t>(), scan_dropped);
  EXPECT_FALSE(s["clock_offsets_s"].contains("ODOM"));  // latency and jitter, not a clock

  // The IMU's clock ahead makes the estimator drop the odometry as late; corrected, the error falls.
  const double before = s["ate_before"], after = s["ate_after"];
  EXPECT_LT(after, 0.5 * before);
  EXPECT_LT(after, 0.1);
  EXPECT_GT(s["late_rejected_before"].get<int64_t>(), s["late_rejected_after"].get<int64_t>());
  EXPECT_EQ(read_json(file("eval-before.json"))["ate"]["rmse"].get<double>(), before);
  EXPECT_EQ(s["report"], file("report/index.html"));
}

TEST_F(DemoCli, ReportRendersEveryPlotInChromium) {
  const std::string page = file("report/index.html");
  for (const char* png : {"trajectories.png", "error_timeline.png", "latency.png", "interarrival.png", "skew.png",
                          "slam_map_0.png"}) {
    EXPECT_TRUE(std::filesystem::exists(file(std::string("report/") + png))) << png;
  }
  std::string dom;
  const int plots = rendered_attribute(page, "data-plots", &dom);
  EXPECT_GE(plots, 7) << dom.substr(0, 2000);  // trajectories, error, latency, inter-arrival, skew, two maps
  EXPECT_EQ(rendered_attribute(page, "data-plots-drawn"), plots);
  EXPECT_EQ(rendered_attribute(page, "data-plots-blank"), 0);
  // The page names the fault in words and opens offline: nothing is fetched from elsewhere.
  EXPECT_NE(dom.find("IMU"), std::string::npos);
  EXPECT_NE(dom.find("ahead of arrival"), std::string::npos);
  EXPECT_EQ(dom.find("src=\"http"), std::string::npos);
  EXPECT_EQ(dom.find("href=\"http"), std::string::npos);
  // The data behind the plots is kept: the error over time of both replays' estimates.
  const auto data = read_json(file("report/report.json"));
  int estimates_with_error = 0;
  for (const auto& e : data["estimates"]) estimates_with_error += e.contains("error") ? 1 : 0;
  EXPECT_GE(estimates_with_error, 4);  // ODOM, both EKF_ODOM and both SLAM_POSE
}

// The pages of the demo, the drone demo, the arm and the Nav2 bag, as a person opens them: issue 28.
TEST_F(DemoCli, ReportPageDrawsItsZoomableCharts) {
  if (!have_chromium()) GTEST_SKIP() << "chromium missing";
  check_page(file("report/index.html"), "demo", 2);  // the error over time, ODOM's latency
  std::ifstream in(file("report/index.html"));
  const std::string html((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // One error far above the others (EKF_ODOM as logged): a log axis, said.
  EXPECT_NE(html.find("position error [m], log"), std::string::npos);
  // A constant latency is a line of text, not a one-bar histogram.
  EXPECT_NE(html.find("Constant latency, not drawn: "), std::string::npos);
  // The summary's ATE is the table's: the same number, its alignment said.
  const double before = read_json(file("eval-before.json"))["ate"]["rmse"];
  char said[32];
  std::snprintf(said, sizeof said, "<b>%.3f m</b>", before);
  EXPECT_NE(html.find(said), std::string::npos) << said;
  EXPECT_NE(html.find("posyaw alignment, as in the table"), std::string::npos);
}

TEST(ReportPages, DroneDemo) {
  if (!have_chromium()) GTEST_SKIP() << "chromium missing";
  test::TempDir dir;
  const auto r = driftlab("demo --drone -o " + dir.path());
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string page = dir.file("report/index.html");
  check_page(page, "drone", 2);
  std::ifstream in(page);
  const std::string html((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // The summary card gives the table's se3 ATE and says so, with the plotted (posyaw) one beside it.
  EXPECT_NE(html.find("se3 alignment, as in the table; plotted aligned in position and yaw"), std::string::npos);
  // Inputs the estimator rejected nothing of are named, not drawn as empty panels.
  EXPECT_NE(html.find("Nothing rejected, not drawn: "), std::string::npos);
  // The page leads with diagnose's headline: the IMU's clock ahead (the cause), not its reordering (the symptom).
  const std::string headline = diagnose_headline(dir.file("sim.lcm"));
  EXPECT_EQ(headline.rfind("IMU: stamps are ", 0), 0u) << headline;
  EXPECT_NE(headline.find("ahead of arrival"), std::string::npos) << headline;
  EXPECT_EQ(page_headline(page), headline);
  const auto data = read_json(dir.file("report/report.json"));
  EXPECT_EQ(data["summary"]["worst_stream"]["name"], "IMU");
  // The flight flown again is drawn with the other: its estimate scored against its own truth, drawn too.
  ASSERT_EQ(data["other_references"].size(), 1u);
  EXPECT_EQ(data["other_references"][0]["label"], "restamped.lcm:GROUND_TRUTH");
  std::map<std::string, nlohmann::json> estimates;
  for (const auto& e : data["estimates"]) estimates[e["label"]] = e;
  ASSERT_TRUE(estimates.count("sim.lcm:VEHICLE_ODOM"));
  ASSERT_TRUE(estimates.count("restamped.lcm:VEHICLE_ODOM"));
  EXPECT_EQ(estimates["restamped.lcm:VEHICLE_ODOM"]["reference"], "restamped.lcm:GROUND_TRUTH");
  EXPECT_FALSE(estimates["sim.lcm:VEHICLE_ODOM"].contains("reference"));  // the first log's
  // Flown again with corrected clocks, its estimate is the better one (the table's se3 ATE says so too).
  EXPECT_LT(estimates["restamped.lcm:VEHICLE_ODOM"]["ate_rmse"].get<double>(),
            estimates["sim.lcm:VEHICLE_ODOM"]["ate_rmse"].get<double>());
  EXPECT_NE(html.find("restamped.lcm:VEHICLE_ODOM (RMS "), std::string::npos);  // in the error over time
  EXPECT_NE(html.find("A run flown again is drawn with the others"), std::string::npos);
}

// A replay's 2D SLAM: each loop test drawn on the trajectory as last optimised, in the counts the SLAM reported.
TEST(ReportPages, SlamLoopClosures) {
  if (!have_chromium()) GTEST_SKIP() << "chromium missing";
  test::TempDir dir;
  auto r = driftlab("sim --duration 120 --seed 1 -o " + dir.file("sim.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  r = driftlab("replay " + dir.file("sim.lcm") + " --modules slam --json -o " + dir.file("slam.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto metrics = nlohmann::json::parse(r.out)["modules"][0]["metrics"];
  r = driftlab("report " + dir.file("sim.lcm") + " " + dir.file("slam.lcm") + " -o " + dir.file("report"));
  ASSERT_EQ(r.code, 0) << r.err;
  check_page(dir.file("report/index.html"), "slam", 1);
  EXPECT_TRUE(std::filesystem::exists(dir.file("report/slam_loops_0.png")));
  const auto data = read_json(dir.file("report/report.json"));
  ASSERT_EQ(data["loops"].size(), 1u);
  const auto& loops = data["loops"][0];
  EXPECT_EQ(loops["label"], "slam.lcm:SLAM_LOOPS");
  // The trajectory as last optimised, not an estimate with poses at the same stamps (SLAM_POSE, published as the
  // scans came).
  EXPECT_EQ(loops["trajectory"], "slam.lcm:SLAM_TRAJECTORY");
  const auto& counts = loops["counts"];
  EXPECT_GT(metrics["loop_closures"].get<int64_t>(), 10);  // the robot drives its loop again
  EXPECT_EQ(counts.value("accepted", 0) - counts.value("undone", 0), metrics["loop_closures"].get<int64_t>());
  int64_t records = 0;
  for (const auto& [outcome, n] : counts.items()) records += n.get<int64_t>();
  EXPECT_EQ(loops["tests"].size(), static_cast<size_t>(records));  // every keyframe of every test on the path
  EXPECT_GE(records, metrics["loop_tests"].get<int64_t>());
}

TEST(ReportPages, ArmDemo) {
  if (!have_chromium()) GTEST_SKIP() << "chromium missing";
  test::TempDir dir;
  auto r = driftlab("sim " + std::string(DRIFTLAB_SOURCE_DIR) +
                    "/sim/scenarios/manipulator_latency.yaml --duration 20 -o " + dir.file("late.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  r = driftlab("eval --arm " + dir.file("late.lcm") + " --json-out " + dir.file("arm.json"));
  ASSERT_EQ(r.code, 0) << r.err;
  r = driftlab("report " + dir.file("late.lcm") + " --eval " + dir.file("arm.json") + " -o " + dir.file("report"));
  ASSERT_EQ(r.code, 0) << r.err;
  check_page(dir.file("report/index.html"), "arm", 1);
  std::ifstream in(dir.file("report/index.html"));
  const std::string html((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(html.find("latency.png"), std::string::npos);  // every stream's latency constant: said, not drawn
  EXPECT_NE(html.find("latency is constant (ARM_CMD 120.0 ms"), std::string::npos);
  // The page leads with diagnose's headline: the 120 ms command loop, the arm's worst stream.
  const std::string headline = diagnose_headline(dir.file("late.lcm"));
  EXPECT_EQ(headline.rfind("ARM_CMD: the joints (JOINT_STATES) follow its commands 12", 0), 0u) << headline;
  EXPECT_EQ(page_headline(dir.file("report/index.html")), headline);
  const auto data = read_json(dir.file("report/report.json"));
  EXPECT_EQ(data["summary"]["worst_stream"]["name"], "ARM_CMD");
  // The end effector (EE_TRUTH, of panda_hand_tcp) is no estimate of the base's GROUND_TRUTH (base_link): drawn
  // apart, never overlaid on it and scored against it.
  ASSERT_EQ(data["apart"].size(), 1u);
  EXPECT_EQ(data["apart"][0]["label"], "late.lcm:EE_TRUTH");
  EXPECT_EQ(data["apart"][0]["body"], "panda_hand_tcp");
  EXPECT_EQ(data["apart"][0]["not_of"], "base_link");
  ASSERT_EQ(data["estimates"].size(), 1u);
  EXPECT_EQ(data["estimates"][0]["label"], "late.lcm:ODOM");
  EXPECT_NE(html.find("drawn apart, as logged, never overlaid on it"), std::string::npos);
  EXPECT_EQ(html.find("EE_TRUTH (RMS"), std::string::npos);  // no error over time against the base
}

TEST(ReportCli, WithoutDygraphsThePageKeepsItsPicturesAndSaysWhy) {
  test::TempDir dir;
  const auto r = test::run_capture("DRIFTLAB_DYGRAPHS_DIR=" + dir.file("none") + " " + kDriftlab + " report " +
                                   std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm -o " + dir.path());
  ASSERT_EQ(r.code, 0) << r.err;
  std::ifstream in(dir.file("index.html"));
  const std::string html((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(html.find("needs libjs-dygraphs"), std::string::npos);
  EXPECT_EQ(html.find("new Dygraph("), std::string::npos);
  if (!have_chromium()) GTEST_SKIP() << "chromium missing";
  // The trajectories and the error over time; its latencies are constant and its intervals its periods: said in
  // "Not drawn", never one-bar histograms and flat lines.
  const int plots = rendered_attribute(dir.file("index.html"), "data-plots");
  EXPECT_GE(plots, 2);
  EXPECT_EQ(rendered_attribute(dir.file("index.html"), "data-plots-drawn"), plots);
}

TEST(DemoText, EndsWithTheFiveLineSummary) {
  test::TempDir dir;
  const auto r = driftlab("demo --duration 15 -o " + dir.path());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto tail = r.out.substr(r.out.rfind("\n\n") + 2);
  EXPECT_EQ(std::count(tail.begin(), tail.end(), '\n'), 5) << tail;
  for (const char* line : {"worst stream:", "clocks ahead:", "drops:", "ATE:", "report:"}) {
    EXPECT_NE(tail.find(line), std::string::npos) << line << " in\n" << tail;
  }
}

TEST(ReportCli, DiagnosesTheLogItselfWhenGivenNoJson) {
  test::TempDir dir;
  const auto r = driftlab("report " + std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm -o " + dir.path());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto data = read_json(dir.file("report.json"));
  EXPECT_EQ(data["diagnosis"]["channels"].size(), 7u);
  EXPECT_EQ(data["reference"]["label"], "sample.lcm:GROUND_TRUTH");  // as given
  ASSERT_EQ(data["estimates"].size(), 1u);  // ODOM
  EXPECT_EQ(data["estimates"][0]["label"], "sample.lcm:ODOM");
  // The trajectories and the error over time; its latencies are constant and its intervals its periods: said in
  // "Not drawn", never one-bar histograms and flat lines.
  const int plots = rendered_attribute(dir.file("index.html"), "data-plots");
  EXPECT_GE(plots, 2);
  EXPECT_EQ(rendered_attribute(dir.file("index.html"), "data-plots-drawn"), plots);
}

// A Gazebo bag recorded with use_sim_time (stamps count from 978 s, the bag's times are dates): the report draws
// each stream's latency as diagnose judges it, through its clock's mapping to arrival, never as the 56 years
// between two clocks; /tf_static (timeless to tf2) has none; AMCL's poses in 'map' and odometry in 'odom' are drawn
// aligned, never overlaid as they are; labels name the bag, not its cached conversion.
TEST(ReportCli, ASimTimeBagIsDrawnOnItsOwnClock) {
  const std::string bag = test::shared_data("bags/nav2_turtlebot.mcap");
  test::TempDir dir;
  const auto r = driftlab("report " + bag + " -o " + dir.path());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto data = read_json(dir.file("report.json"));
  std::map<std::string, nlohmann::json> diagnosed;
  for (const auto& c : data["diagnosis"]["channels"]) diagnosed[c["name"]] = c;
  int drawn = 0;
  for (const auto& s : data["streams"]) {
    const std::string name = s["channel"];
    if (name == "/tf_static") {
      EXPECT_TRUE(s["latency"].empty());
      continue;
    }
    ASSERT_FALSE(s["latency"].empty()) << name;
    EXPECT_TRUE(s["mapped_clock"].get<bool>()) << name;
    std::vector<double> lat = s["latency"];
    std::sort(lat.begin(), lat.end());
    // The median of what is drawn is the diagnosis' (0.5 ms: the report maps each stamp from its arrival and
    // latency rounded to the microsecond; the diagnosis from the stamp itself). AMCL's worst is 5 s late and /tf
    // carries transforms post-dated by a second (AMCL's transform_tolerance): nothing beyond 10 s either way.
    EXPECT_NEAR(lat[lat.size() / 2], diagnosed[name]["latency_s"]["p50"].get<double>(), 5e-4) << name;
    EXPECT_LT(lat.back(), 10.0) << name;
    EXPECT_GT(lat.front(), -10.0) << name;
    ++drawn;
  }
  EXPECT_EQ(drawn, 3);  // /amcl_pose, /odom, /tf
  // The page names the bag, not its cached conversion.
  EXPECT_EQ(data["title"], "driftlab report: nav2_turtlebot.mcap");
  if (have_chromium()) check_page(dir.file("index.html"), "nav2", 3);  // a latency chart per stream
  EXPECT_EQ(data["logs"][0]["path"], bag);
  ASSERT_EQ(data["estimates"].size(), 2u);
  EXPECT_TRUE(data["unmatched"].empty());
  for (const auto& e : data["estimates"]) {
    const std::string label = e["label"];
    EXPECT_EQ(label.rfind("nav2_turtlebot.mcap:", 0), 0u) << label;
    if (label.find("/amcl_pose") != std::string::npos) {
      EXPECT_EQ(e["aligned_to"], "/odom");
      EXPECT_EQ(label, "nav2_turtlebot.mcap:/amcl_pose (aligned to /odom)");
    }
  }
}

TEST(ReportCli, BadInputIsOneLineNamingTheFile) {
  test::TempDir dir;
  const std::string sample = std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm";
  test::write_file(dir.file("bad.json"), {'{', 'x'});
  auto r = driftlab("report " + sample + " --diagnosis " + dir.file("bad.json") + " -o " + dir.file("out"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("bad.json: not JSON"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1);
  const std::string odd = R"({"channels": [{"name": "IMU", "drops": 3}]})";
  test::write_file(dir.file("odd.json"), std::vector<uint8_t>(odd.begin(), odd.end()));
  r = driftlab("report " + sample + " --diagnosis " + dir.file("odd.json") + " -o " + dir.file("out"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("odd.json: not the JSON of driftlab diagnose"), std::string::npos) << r.err;
  test::write_file(dir.file("other.json"), {'{', '}'});
  r = driftlab("report " + sample + " --eval " + dir.file("other.json") + " -o " + dir.file("out"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("not the JSON of driftlab eval"), std::string::npos) << r.err;
  r = driftlab("report " + std::string(DRIFTLAB_TEST_DATA) + "/empty.lcm -o " + dir.file("out"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("empty.lcm"), std::string::npos) << r.err;
  r = driftlab("report " + dir.file("missing.lcm") + " -o " + dir.file("out"));
  EXPECT_EQ(r.code, 2);
  EXPECT_FALSE(std::filesystem::exists(dir.file("out/index.html")));
}

}  // namespace
}  // namespace driftlab
