// End-to-end tests of `driftlab sim`: the default scenario, --faults, --seed and --json, Ctrl-C, and bad input
// (one line naming the file and the place, exit code 2, no log left behind).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <thread>

#include "tests/test_util.h"

namespace driftlab {
namespace {

const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";
const std::string kSim = std::string(DRIFTLAB_SOURCE_DIR) + "/sim";

test::CmdResult driftlab(const std::string& args) { return test::run_capture(kDriftlab + " " + args); }

void write(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

bool exists(const std::string& path) { return std::filesystem::exists(path); }

TEST(SimCli, DefaultScenarioJsonSummary) {
  test::TempDir dir;
  const auto r = driftlab("sim --duration 2 --json -o " + dir.file("s.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["log"], dir.file("s.lcm"));
  EXPECT_EQ(j["faults"], dir.file("s.faults.json"));
  EXPECT_DOUBLE_EQ(j["simulated_s"].get<double>(), 2.0);
  EXPECT_EQ(j["messages"]["IMU"], 401);
  EXPECT_FALSE(j["interrupted"].get<bool>());
  EXPECT_TRUE(exists(dir.file("s.lcm")));
  EXPECT_TRUE(exists(dir.file("s.faults.json")));
  EXPECT_FALSE(exists(dir.file("s.lcm.partial")));
  // driftlab info reads it.
  const auto info = driftlab("info --json " + dir.file("s.lcm"));
  ASSERT_EQ(info.code, 0) << info.err;
  EXPECT_EQ(nlohmann::json::parse(info.out)["problems"].size(), 0u);
}

TEST(SimCli, FaultsFileReplacesTheScenarios) {
  test::TempDir dir;
  write(dir.file("f.yaml"), "streams:\n  ODOM:\n    clock_offset_s: -0.25\n");
  const auto r = driftlab("sim --duration 2 --seed 9 --faults " + dir.file("f.yaml") + " -o " + dir.file("s.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  std::ifstream f(dir.file("s.faults.json"));
  const auto j = nlohmann::json::parse(f);
  ASSERT_EQ(j["faults"].size(), 1u);
  EXPECT_EQ(j["faults"][0]["channel"], "ODOM");
  EXPECT_EQ(j["faults"][0]["kind"], "clock_offset");
  EXPECT_EQ(j["seed"], 9);
  // Human summary names the log and the faults.
  EXPECT_NE(r.out.find("simulated 2.0 s of indoor"), std::string::npos) << r.out;
}

TEST(SimCli, CtrlCClosesAValidLog) {
  test::TempDir dir;
  const std::string out = dir.file("cut.lcm");
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    execl(kDriftlab.c_str(), "driftlab", "sim", "-o", out.c_str(), nullptr);
    _exit(127);
  }
  // Wait until it is simulating (the partial log exists), then interrupt.
  for (int i = 0; i < 200 && !exists(out + ".partial"); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  kill(pid, SIGINT);
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_FALSE(exists(out + ".partial"));
  std::vector<Problem> problems;
  const auto events = test::read_all(out, &problems);
  EXPECT_TRUE(problems.empty());
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back().channel, "FAULTS");
  EXPECT_TRUE(exists(dir.file("cut.faults.json")));
}

/// A copy of the default scenario with `from` replaced by `to` (paths made absolute).
std::string scenario_with(const test::TempDir& dir, const std::string& from, const std::string& to) {
  const auto bytes = test::read_file(kSim + "/scenarios/indoor.yaml");
  std::string s(bytes.begin(), bytes.end());
  for (std::size_t p; (p = s.find("../")) != std::string::npos;) s.replace(p, 3, kSim + "/");
  if (!from.empty()) {
    const auto p = s.find(from);
    EXPECT_NE(p, std::string::npos) << from;
    s.replace(p, from.size(), to);
  }
  write(dir.file("sc.yaml"), s);
  return dir.file("sc.yaml");
}

/// Line (1-based) of the first occurrence of `text` in the default scenario.
int line_of(const std::string& text) {
  const auto bytes = test::read_file(kSim + "/scenarios/indoor.yaml");
  const std::string s(bytes.begin(), bytes.end());
  return 1 + static_cast<int>(std::count(s.begin(), s.begin() + static_cast<long>(s.find(text)), '\n'));
}

struct BadCase {
  const char* name;
  const char* from;
  const char* to;
  const char* expect;  ///< in the message, after "sc.yaml:LINE: " when line_text is given
  const char* line_text;
};

class SimBadInput : public ::testing::TestWithParam<BadCase> {};

TEST_P(SimBadInput, OneLineExitTwoNoLog) {
  const BadCase& c = GetParam();
  test::TempDir dir;
  const std::string sc = scenario_with(dir, c.from, c.to);
  const auto r = driftlab("sim " + sc + " --duration 1 -o " + dir.file("out.lcm"));
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  std::string prefix = sc + ":";
  if (c.line_text != nullptr) prefix += std::to_string(line_of(c.line_text)) + ":";
  EXPECT_EQ(r.err.rfind("driftlab: " + prefix, 0), 0u) << r.err;
  EXPECT_NE(r.err.find(c.expect), std::string::npos) << r.err;
  EXPECT_FALSE(exists(dir.file("out.lcm")));
  EXPECT_FALSE(exists(dir.file("out.lcm.partial")));
}

INSTANTIATE_TEST_SUITE_P(
    Scenarios, SimBadInput,
    ::testing::Values(
        BadCase{"MalformedYaml", "sensors:", "sensors: [", "", nullptr},
        BadCase{"UnknownSensorType", "type: imu,", "type: sonar,", "unknown sensor type 'sonar'", "type: imu,"},
        BadCase{"NegativeRate", "rate: 200}", "rate: -200}", "IMU.rate = -200 must be > 0", "type: imu,"},
        BadCase{"UnknownKey", "seed: 1", "sead: 1", "unknown key 'sead'", "seed: 1"},
        BadCase{"SensorOnMissingLink", "link: imu_link", "link: imu_lnk",
                "sensor IMU is on link 'imu_lnk', which robot 'diffbot'", "type: imu,"},
        BadCase{"FaultOnUnknownChannel", "    IMU:\n      clock_offset_s", "    IMUU:\n      clock_offset_s",
                "faults name channel 'IMUU'", nullptr},
        BadCase{"BadFaultValue", "drop_probability: 0.02", "drop_probability: 2", "SCAN.drop_probability = 2",
                "drop_probability: 0.02"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(SimCli, MalformedUrdfNamesTheUrdfLine) {
  test::TempDir dir;
  write(dir.file("bad.urdf"), "<?xml version=\"1.0\"?>\n<robot name=\"x\">\n  <link name=\"a\">\n</robot>\n");
  const std::string sc = scenario_with(dir, kSim + "/robots/diffbot.urdf", dir.file("bad.urdf"));
  // (scenario_with made the URDF path absolute before replacing it)
  const auto r = driftlab("sim " + sc + " --duration 1 -o " + dir.file("out.lcm"));
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.err.rfind("driftlab: " + dir.file("bad.urdf") + ":4: malformed XML", 0), 0u) << r.err;
  EXPECT_FALSE(exists(dir.file("out.lcm")));
}

/// The manipulator scenario on a copy of the mobile Panda's URDF with `from` replaced by `to` (regex, first match).
struct BadArm {
  const char* name;
  const char* from;
  const char* to;
  const char* element;  // what the message names
  const char* why;
};

class SimCliBadArm : public ::testing::TestWithParam<BadArm> {};

TEST_P(SimCliBadArm, OneLineNamingFileAndElementExitTwo) {
  const BadArm& c = GetParam();
  test::TempDir dir;
  const auto u = test::read_file(kSim + "/robots/mobile_panda.urdf");
  const std::string urdf = std::regex_replace(std::string(u.begin(), u.end()), std::regex(c.from), c.to,
                                              std::regex_constants::format_first_only);
  write(dir.file("arm.urdf"), urdf);
  const auto sb = test::read_file(kSim + "/scenarios/manipulator.yaml");
  std::string sc(sb.begin(), sb.end());
  for (std::size_t p; (p = sc.find("../")) != std::string::npos;) sc.replace(p, 3, kSim + "/");
  sc.replace(sc.find(kSim + "/robots/mobile_panda.urdf"), (kSim + "/robots/mobile_panda.urdf").size(),
             dir.file("arm.urdf"));
  write(dir.file("sc.yaml"), sc);
  const auto r = driftlab("sim " + dir.file("sc.yaml") + " --duration 1 -o " + dir.file("out.lcm"));
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  // The line of the element in the broken file.
  const std::string element = c.element;
  const int line =
      1 + static_cast<int>(std::count(urdf.begin(), urdf.begin() + static_cast<long>(urdf.find(element)), '\n'));
  EXPECT_EQ(r.err.rfind("driftlab: " + dir.file("arm.urdf") + ":" + std::to_string(line) + ": ", 0), 0u) << r.err;
  EXPECT_NE(r.err.find(c.why), std::string::npos) << r.err;
  EXPECT_FALSE(exists(dir.file("out.lcm")));
}

INSTANTIATE_TEST_SUITE_P(
    Arm, SimCliBadArm,
    ::testing::Values(
        BadArm{"MissingChildLink", "<child link=\"panda_link4\"/>", "<child link=\"panda_link44\"/>",
               "<joint name=\"panda_joint4\"", "joint 'panda_joint4': its child link 'panda_link44' does not exist"},
        // The arm's mount hung below its own third link: panda_link0 -> ... -> panda_link3 -> panda_link0.
        BadArm{"Loop", "(<joint name=\"arm_mount\" type=\"fixed\">\\s*<parent link=\")[a-z_]+", "$1panda_link3",
               "<joint name=\"arm_mount\"", "joint 'arm_mount' closes a loop"},
        BadArm{"JointWithoutLimits", "<joint name=\"panda_joint4\" type=\"revolute\">([\\s\\S]*?)<limit[^>]*/>",
               "<joint name=\"panda_joint4\" type=\"continuous\">$1", "<joint name=\"panda_joint4\"",
               "joint 'panda_joint4': is continuous, without position limits; the joint trajectory controller needs"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(SimCli, MissingScenarioFile) {
  const auto r = driftlab("sim /nonexistent/scenario.yaml");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.err, "driftlab: /nonexistent/scenario.yaml: cannot open the scenario file: No such file or directory\n");
}

}  // namespace
}  // namespace driftlab
