// Tests for analyzers/diagnosis_text.h: the worst severity `diagnose --fail-on` judges by, a flight log's problems
// ahead of the streams', and the HTML page, which shows what it quotes (channel names come from the recording).
#include "analyzers/diagnosis_text.h"

#include <gtest/gtest.h>

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
