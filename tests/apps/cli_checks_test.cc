// The range check of number options (apps/cli_checks.h): the config layer's ranges and texts, for options.
#include "apps/cli_checks.h"

#include <gtest/gtest.h>

#include <string>

namespace driftlab::apps {
namespace {

std::string check(const CLI::Validator& v, std::string text) { return v(text); }

TEST(InRange, SaysWhatIsWrongWithTheValueInOneLine) {
  const CLI::Validator rate = in_range(config::above(0, 1e6));
  EXPECT_EQ(check(rate, "1"), "");
  EXPECT_EQ(check(rate, "1e6"), "");
  EXPECT_EQ(check(rate, "-1"), "must be > 0, got -1");
  EXPECT_EQ(check(rate, "0"), "must be > 0, got 0");
  EXPECT_EQ(check(rate, "1e300"), "must be <= 1e+06, got 1e300");
  EXPECT_EQ(check(rate, "nan"), "must be a finite number, got nan");
  EXPECT_EQ(check(rate, "-inf"), "must be a finite number, got -inf");
  // Beyond double: strtod gives inf; the text is cut, never printed in full.
  EXPECT_EQ(check(rate, std::string(400, '9')), "must be a finite number, got 9999999999999999... (400 characters)");
  // Not a number: the option's own conversion says so, in its words.
  EXPECT_EQ(check(rate, "fast"), "");
}

TEST(InRange, NamesTheUnitAsTheConfigLayerDoes) {
  const CLI::Validator window = in_range(config::between(0, 60), "s");
  EXPECT_EQ(check(window, "60"), "");
  EXPECT_EQ(check(window, "61"), "is outside 0..60 s, got 61");
  EXPECT_EQ(check(window, "-0.5"), "is outside 0..60 s, got -0.5");
}

TEST(InRange, ShowsTheIntervalInHelpAndIsFoundByItsName) {
  EXPECT_EQ(interval(config::between(0, 60)), "[0, 60]");
  EXPECT_EQ(interval(config::above(0, 1e6)), "(0, 1e+06]");
  EXPECT_EQ(interval(config::at_least(1)), "[1, inf)");
  CLI::App app;
  double rate = 1;
  CLI::Option* opt = app.add_option("--rate", rate)->check(in_range(kPaceRate));
  EXPECT_NE(opt->get_validator(kRangeCheck), nullptr);
  EXPECT_EQ(opt->get_type_name(), "FLOAT:(0, 1e+06]");
  app.parse("--rate 2", false);
  EXPECT_EQ(rate, 2);
  EXPECT_THROW(app.parse("--rate 0", false), CLI::ValidationError);
}

}  // namespace
}  // namespace driftlab::apps
