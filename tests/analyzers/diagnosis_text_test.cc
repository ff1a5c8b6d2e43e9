// Tests for analyzers/diagnosis_text.h and the summary of diagnosis_json.h: the worst severity `diagnose --fail-on`
// judges by, a flight log's problems ahead of the streams', the HTML page, which shows what it quotes (channel
// names come from the recording), and the headline the report, the demo and the batches read from a diagnosis.
#include "analyzers/diagnosis_text.h"

#include <gtest/gtest.h>

#include <map>
#include <string>

namespace driftlab::analyzers {
namespace {

ChannelTiming channel(const std::string& name, const std::string& verdict) {
  ChannelTiming c;
  c.name = name;
  c.verdict = verdict;
  return c;
}

TEST(DiagnosisText, TheWorstSeverityIsTheWorstVerdictOrAProblemOfTheWholeLog) {
  DiagnoseRun run;
  run.diagnosis.log = "run.lcm";
  run.diagnosis.channels = {channel("IMU", "ok"), channel("SCAN", "ok")};
  DiagnosisText text = diagnosis_text(run);
  EXPECT_EQ(worst_severity(run.diagnosis, text), Severity::kOk);
  EXPECT_TRUE(text.problems.empty());
  run.diagnosis.channels[1].verdict = "warn";
  EXPECT_EQ(worst_severity(run.diagnosis, diagnosis_text(run)), Severity::kWarn);
  run.diagnosis.channels[0].verdict = "fault";
  EXPECT_EQ(worst_severity(run.diagnosis, diagnosis_text(run)), Severity::kFault);
  // Every stream fine, but a problem of the log as a whole (here, the flight log's): a warning.
  run.diagnosis.channels = {channel("IMU", "ok")};
  run.flight.present = true;
  run.flight.problems = {"the logger dropped 3 times"};
  text = diagnosis_text(run);
  ASSERT_FALSE(text.problems.empty());
  EXPECT_EQ(text.problems.front(), "the logger dropped 3 times");  // the flight log's first
  EXPECT_EQ(worst_severity(run.diagnosis, text), Severity::kWarn);
}

TEST(DiagnosisText, TheHtmlPageEscapesWhatItQuotes) {
  DiagnoseRun run;
  run.diagnosis.log = "a<b>&c.lcm";
  run.diagnosis.channels = {channel("/scan<1>", "ok")};
  const DiagnosisText text = diagnosis_text(run);
  const std::string page = diagnosis_html(run.diagnosis, text);
  EXPECT_NE(page.find("a&lt;b&gt;&amp;c.lcm"), std::string::npos);
  EXPECT_EQ(page.find("a<b>"), std::string::npos);
  EXPECT_NE(page.find("/scan&lt;1&gt;"), std::string::npos);
  EXPECT_NE(page.find("<li>none</li>"), std::string::npos);  // no problems
}

}  // namespace
}  // namespace driftlab::analyzers

namespace driftlab::analyzers {
namespace {

/// The sample log's diagnosis as `diagnose --json-out` writes it.
nlohmann::json sample_diagnosis() {
  auto run = run_diagnosis(std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm", {});
  EXPECT_TRUE(run) << run.error().message;
  return to_json(run->diagnosis);
}

TEST(DiagnosisSummary, TheWorstStreamItsClockAndDropsFromADiagnosesJson) {
  nlohmann::json d = sample_diagnosis();
  auto s = summarize(d);
  ASSERT_TRUE(s) << s.error().message;
  // The sample's SCAN is stamped 95.7 ms ahead of its arrival: the one fault, its cause the clock.
  ASSERT_TRUE(s->worst_stream);
  EXPECT_EQ(s->worst_stream->name, "SCAN");
  EXPECT_EQ(s->worst_stream->verdict, Severity::kFault);
  EXPECT_EQ(s->worst_stream->causes, std::vector<std::string>{"clock"});
  EXPECT_EQ(s->fault_streams, 1);
  EXPECT_EQ(s->warn_streams, 0);
  EXPECT_TRUE(s->drops.empty());

  // The same log had IMU's clock found 12 ms ahead and ODOM lost 7 packets by sequence number: both counted. A
  // clock 0.5 ms ahead is below what one log can tell from latency, and one on a mapped (simulation-time) domain
  // has no offset of its own.
  for (auto& c : d["channels"]) {
    if (c["name"] == "IMU") c["clock"] = {{"offset_s", 0.012}};
    if (c["name"] == "TF") c["clock"] = {{"offset_s", 0.0005}};
    if (c["name"] == "ODOM") c["drops"]["seq_gaps"] = 7;
    if (c["name"] == "CMD_VEL") {
      c["clock"] = {{"offset_s", 0.2}};
      c["domain"] = 1;
    }
  }
  d["clock_domains"].push_back({{"mapped", true}});
  s = summarize(d);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->clocks_ahead_s, (std::map<std::string, double>{{"IMU", 0.012}}));
  EXPECT_EQ(s->drops, (std::map<std::string, int64_t>{{"ODOM", 7}}));
  const nlohmann::json j = to_json(*s);
  EXPECT_EQ(j["worst_stream"]["verdict"], "fault");
  EXPECT_EQ(j["drops"]["ODOM"], 7);

  // Not a diagnosis: one line, no exception.
  auto bad = summarize(nlohmann::json{{"channels", {{{"name", "IMU"}}}}});
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().message.find('\n'), std::string::npos);
  EXPECT_NE(bad.error().message.find("not a diagnosis"), std::string::npos) << bad.error().message;
}

TEST(DiagnosisSummary, AnUnflaggedLogHasNoWorstStream) {
  nlohmann::json d = sample_diagnosis();
  for (auto& c : d["channels"]) {
    c["verdict"] = "ok";
    c["reasons"] = nlohmann::json::array();
    c["causes"] = nlohmann::json::array();
  }
  auto s = summarize(d);
  ASSERT_TRUE(s);
  EXPECT_FALSE(s->worst_stream);
  EXPECT_TRUE(to_json(*s)["worst_stream"].is_null());
  EXPECT_EQ(severity_from_name("warn"), Severity::kWarn);
  EXPECT_EQ(severity_from_name("nonsense"), Severity::kOk);
}

}  // namespace
}  // namespace driftlab::analyzers
