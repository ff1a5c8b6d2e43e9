// What the command line says when it is used wrong (apps/tools.cc: usage_error_line), and diagnose's options for
// scripts and CI (--fail-on, -c), end to end through the program.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>

#include "tests/test_util.h"

namespace driftlab {
namespace {

const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";
const std::string kSample = std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm";

test::CmdResult driftlab(const std::string& args) { return test::run_capture(kDriftlab + " " + args); }

// Every usage error is one line on stderr, exit code 2, naming the --help of the command it was given to.
void expect_usage_error(const test::CmdResult& r, const std::string& line) {
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.err, "driftlab: " + line + "\n");
  EXPECT_EQ(r.out, "");
}

TEST(UsageErrors, AMistypedCommandGetsTheOneItWasCloseTo) {
  expect_usage_error(driftlab("diagnos " + kSample),
                     "'diagnos' is not a command of 'driftlab': did you mean 'diagnose'? (see 'driftlab --help')");
  // Two neighbours swapped is one edit.
  expect_usage_error(driftlab("daignose " + kSample),
                     "'daignose' is not a command of 'driftlab': did you mean 'diagnose'? (see 'driftlab --help')");
  expect_usage_error(driftlab("export mcpa " + kSample + " -o x.mcap"),
                     "'mcpa' is not a command of 'driftlab export': did you mean 'mcap'? (see 'driftlab export "
                     "--help')");
  // Nothing close: no guess, only where to look.
  expect_usage_error(driftlab("xyzzy"), "'xyzzy' is not a command of 'driftlab' (see 'driftlab --help')");
}

TEST(UsageErrors, AMistypedOptionGetsTheOneOfThatCommand) {
  expect_usage_error(driftlab("diagnose " + kSample + " --jsno out.json"),
                     "unknown option '--jsno': did you mean '--json'? (see 'driftlab diagnose --help')");
  expect_usage_error(driftlab("info --jsno " + kSample),
                     "unknown option '--jsno': did you mean '--json'? (see 'driftlab info --help')");
  // --out misspelt leaves the required --out missing: both said.
  expect_usage_error(driftlab("export mcap " + kSample + " --ot x.mcap"),
                     "--out is required; unknown option '--ot': did you mean '--out'? (see 'driftlab export mcap "
                     "--help')");
  // The heavy commands' own programs say it the same way.
  expect_usage_error(driftlab("sim --durration 3"),
                     "unknown option '--durration': did you mean '--duration'? (see 'driftlab sim --help')");
}

TEST(UsageErrors, OtherErrorsPointToTheCommandsHelp) {
  expect_usage_error(driftlab("info"), "log is required (see 'driftlab info --help')");
  expect_usage_error(driftlab("diagnose " + kSample + " --fail-on sometimes"),
                     "--fail-on: sometimes not in {warn,fault} (see 'driftlab diagnose --help')");
}

// --json prints one JSON object and nothing else; --json-out FILE writes the same object and keeps the text: the
// same two options in every command that reports (issue 28).
TEST(JsonOptions, MeanTheSameInEveryCommand) {
  test::TempDir dir;
  const std::string eval = "eval --gt " + kSample + ":GROUND_TRUTH --est " + kSample + ":ODOM";
  for (const std::string& command : {"diagnose " + kSample, "info " + kSample, eval}) {
    SCOPED_TRACE(command);
    const auto printed = driftlab(command + " --json");
    ASSERT_EQ(printed.code, 0) << printed.err;
    const auto object = nlohmann::json::parse(printed.out);  // the whole output is the object
    ASSERT_TRUE(object.is_object());
    const auto text = driftlab(command);
    const auto both = driftlab(command + " --json-out " + dir.file("out.json"));
    ASSERT_EQ(both.code, 0) << both.err;
    EXPECT_EQ(both.out, text.out);  // the text as without it
    const auto bytes = test::read_file(dir.file("out.json"));
    EXPECT_EQ(nlohmann::json::parse(std::string(bytes.begin(), bytes.end())), object);
  }
  // The other reporting commands take both.
  for (const char* command : {"sim", "replay", "recover", "demo", "sweep", "sweep status", "batch status", "run"}) {
    const auto help = driftlab(std::string(command) + " --help");
    EXPECT_NE(help.out.find("--json "), std::string::npos) << command;
    EXPECT_NE(help.out.find("--json-out FILE"), std::string::npos) << command;
  }
}

TEST(JsonOptions, TheOldFileArgumentIsExplained) {
  // `--json FILE` used to write the file; the file would now be read as a log. Said plainly, nothing written.
  test::TempDir dir;
  expect_usage_error(driftlab("diagnose " + kSample + " --json " + dir.file("d.json")),
                     "--json takes no file: it prints the JSON; --json-out " + dir.file("d.json") + " writes it");
  expect_usage_error(driftlab("diagnose --json - " + kSample),
                     "--json takes no file: it prints the JSON; --json-out - writes it");
  EXPECT_FALSE(std::filesystem::exists(dir.file("d.json")));
}

TEST(DiagnoseFailOn, ExitsWithThreeWhenAStreamReachesTheLevel) {
  // The golden sample's SCAN is a fault (a source clock 95 ms ahead); its other streams are clean.
  auto plain = driftlab("diagnose " + kSample);
  EXPECT_EQ(plain.code, 0) << plain.err;
  EXPECT_EQ(driftlab("diagnose " + kSample + " --fail-on fault").code, 3);
  EXPECT_EQ(driftlab("diagnose " + kSample + " --fail-on warn").code, 3);
  // The same with only the JSON printed.
  auto json = driftlab("diagnose " + kSample + " --json --fail-on fault");
  EXPECT_EQ(json.code, 3);
  EXPECT_TRUE(nlohmann::json::accept(json.out));
  // Without SCAN nothing is wrong.
  EXPECT_EQ(driftlab("diagnose " + kSample + " -c 'IMU|ODOM' --fail-on warn").code, 0);
}

TEST(DiagnoseChannels, OnlyTheChannelsMatchedAreAnalysed) {
  auto r = driftlab("diagnose " + kSample + " -c 'IMU|SC.*' --json");
  ASSERT_EQ(r.code, 0) << r.err;
  auto j = nlohmann::json::parse(r.out);
  std::vector<std::string> names;
  for (const auto& c : j["channels"]) names.push_back(c["name"].get<std::string>());
  EXPECT_EQ(names, (std::vector<std::string>{"IMU", "SCAN"}));
  // The same findings as in the full diagnosis: a filter leaves streams out, it does not change the others, but
  // for what is measured against the streams left out (the delay behind the first of a burst of peers).
  auto all = nlohmann::json::parse(driftlab("diagnose " + kSample + " --json").out);
  for (auto c : all["channels"]) {
    if (c["name"] != "SCAN") continue;
    auto filtered = j["channels"][1];
    c.erase("peer_delay_s");
    filtered.erase("peer_delay_s");
    EXPECT_EQ(c, filtered);
  }
  expect_usage_error(driftlab("diagnose " + kSample + " -c '('"),
                     "invalid channel regex '(': Mismatched '(' and ')' in regular expression");
}

TEST(ExportMcapChannels, OnlyTheChannelsMatchedAreWritten) {
  const std::string out = testing::TempDir() + "/usage_filtered.mcap";
  auto r = driftlab("export mcap " + kSample + " -c 'IMU|SCAN' -o " + out);
  ASSERT_EQ(r.code, 0) << r.err;
  auto info = driftlab("info --json " + out);
  ASSERT_EQ(info.code, 0) << info.err;
  std::vector<std::string> names;
  const auto j = nlohmann::json::parse(info.out);
  for (const auto& c : j["channels"]) names.push_back(c["name"].get<std::string>());
  // An MCAP import's own bookkeeping channels come back too; the data channels are the two asked for.
  std::erase_if(names, [](const std::string& n) { return n == "CHANNEL_SOURCES" || n == "FOREIGN_SCHEMAS"; });
  EXPECT_EQ(names, (std::vector<std::string>{"IMU", "SCAN"}));
}

}  // namespace
}  // namespace driftlab
