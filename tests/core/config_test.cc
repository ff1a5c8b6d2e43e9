// Tests for core/config.h: a table reads every kind of value, refuses every bad one with one exact line naming the
// file, the line and the dotted key, and renders its reference.
#include "core/config.h"

#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace driftlab::config {
namespace {

enum class Shape { kRound, kSquare };

struct Point {
  double x = 0, y = 0;
};

struct Inner {
  double gain = 2;
  bool on = false;
};

struct Options {
  double rate = 50;
  int beams = 360;
  int64_t stamp = 0;
  uint64_t seed = 1;
  bool loop = true;
  std::string channel = "SCAN";
  std::string method = "ndt";
  Shape shape = Shape::kRound;
  std::array<double, 3> pose = {0, 0, 0};
  Point start;
  Inner inner;                          // a section: inner.gain
  Inner flat;                           // included: gain2, on2 at the top level
  std::map<std::string, Inner> streams;  // a map of sections
  std::vector<double> odd = {1};        // custom: a list of odd numbers
  std::string name;                     // in a section of Options itself: meta.name
};

const Table<Inner>& inner_table() {
  static const auto t = Table<Inner>()
                            .number("gain", &Inner::gain, above(0, 10), "", "how much")
                            .flag("on", &Inner::on, "whether");
  return t;
}

const Table<Inner>& flat_table() {
  static const auto t = Table<Inner>()
                            .number("gain2", &Inner::gain, between(0, 1), "", "a fraction")
                            .flag("on2", &Inner::on, "whether")
                            .check([](const Value& v, Inner& i) -> Status {
                              if (i.on && i.gain == 0) return v["gain2"].error("must be > 0 when on2");
                              return {};
                            });
  return t;
}

const Table<Options>& table() {
  using O = Options;
  static const auto meta = Table<O>().text("name", &O::name, "a name", Text::kNonEmpty).required();
  static const auto t =
      Table<O>()
          .describe("Options for the test.")
          .number("rate", &O::rate, between(0.1, 1000), "Hz", "output rate")
          .integer("beams", &O::beams, between(1, 4096), "", "returns per scan")
          .integer("stamp", &O::stamp, between(0, 9e18), "us", "a time")
          .integer("seed", &O::seed, at_least(0), "", "random seed")
          .flag("loop", &O::loop, "drive again")
          .text("channel", &O::channel, "where from", Text::kNonEmpty)
          .choice("method", &O::method, {"icp", "ndt", "gicp"}, "registration")
          .choice("shape", &O::shape, {{"round", Shape::kRound}, {"square", Shape::kSquare}}, "the footprint")
          .numbers("pose", &O::pose, between(-100, 100), "m, m, rad", "x, y, yaw")
          .numbers("start", &O::start, {&Point::x, &Point::y}, {}, "m", "x, y")
          .section("inner", &O::inner, inner_table(), "a sub-map")
          .include(&O::flat, flat_table())
          .map("streams", &O::streams, "CHANNEL", inner_table(), "per channel")
          .custom<std::vector<double>>(
              "odd", &O::odd, "list of numbers", "", "odd", "odd numbers",
              [](const Value& v, std::vector<double>& out) -> Status {
                if (!v.node().IsSequence()) return v.error("must be a list");
                out.clear();
                for (std::size_t i = 0; i < v.node().size(); ++i) {
                  auto x = v[i].integer();
                  if (!x) return x.error();
                  if (*x % 2 == 0) return v[i].error("must be odd");
                  out.push_back(static_cast<double>(*x));
                }
                return {};
              },
              [](const std::vector<double>& v) { return std::to_string(v.size()) + " numbers"; })
          .shown_default("[1]")
          .section("meta", meta, "about it")
          .required()
          .brief();
  return t;
}

Result<Options> parse(const std::string& yaml) { return table().parse(Value(YAML::Load(yaml), "f.yaml", "opts")); }

std::string error(const std::string& yaml) {
  auto r = parse(yaml);
  return r ? std::string("ok") : r.error().message;
}

TEST(ConfigTable, ReadsEveryKindOfValue) {
  auto o = parse(R"(rate: 1e2
beams: 1e3
stamp: 1763776800000001
seed: 18446744073709551615
loop: no
channel: IMU
method: gicp
shape: square
pose: [1, -2.5, 0.25]
start: [3, 4]
inner: {gain: 3, on: true}
gain2: 0.5
on2: yes
streams:
  IMU: {gain: 4}
  SCAN: {on: true}
odd: [1, 3, 5]
meta: {name: x}
)");
  ASSERT_TRUE(o) << o.error().message;
  EXPECT_EQ(o->rate, 100);
  EXPECT_EQ(o->beams, 1000);                   // a whole number written as a decimal
  EXPECT_EQ(o->stamp, 1763776800000001);       // exact: not through a double
  EXPECT_EQ(o->seed, UINT64_MAX);
  EXPECT_FALSE(o->loop);
  EXPECT_EQ(o->channel, "IMU");
  EXPECT_EQ(o->method, "gicp");
  EXPECT_EQ(o->shape, Shape::kSquare);
  EXPECT_EQ(o->pose, (std::array<double, 3>{1, -2.5, 0.25}));
  EXPECT_EQ(o->start.x, 3);
  EXPECT_EQ(o->start.y, 4);
  EXPECT_EQ(o->inner.gain, 3);
  EXPECT_TRUE(o->inner.on);
  EXPECT_EQ(o->flat.gain, 0.5);
  EXPECT_TRUE(o->flat.on);
  ASSERT_EQ(o->streams.size(), 2u);
  EXPECT_EQ(o->streams.at("IMU").gain, 4);
  EXPECT_FALSE(o->streams.at("IMU").on);
  EXPECT_EQ(o->streams.at("SCAN").gain, 2);  // an entry's defaults are the struct's
  EXPECT_EQ(o->odd, (std::vector<double>{1, 3, 5}));
  EXPECT_EQ(o->name, "x");
}

TEST(ConfigTable, KeysNotGivenKeepTheBase) {
  Options base;
  base.rate = 7;
  base.name = "given";
  auto o = table().parse(Value(YAML::Load("beams: 2\nmeta: {name: y}\n"), "f.yaml", "opts"), base);
  ASSERT_TRUE(o) << o.error().message;
  EXPECT_EQ(o->rate, 7);
  EXPECT_EQ(o->beams, 2);
  // An absent or null map changes nothing, but a required key is still missing.
  EXPECT_EQ(error("meta: {name: y}\n"), "ok");
  auto none = inner_table().parse(Value(YAML::Node(), "f.yaml", "inner"));
  ASSERT_TRUE(none);
  EXPECT_EQ(none->gain, 2);
  EXPECT_EQ(error("{}"), "f.yaml:1: missing key 'opts.meta' (about it)");
  EXPECT_EQ(error("meta: {}\n"), "f.yaml:1: missing key 'opts.meta.name' (a name)");
}

TEST(ConfigTable, RefusesEveryBadValueInOneExactLine) {
  const std::string m = "\nmeta: {name: x}\n";
  const std::pair<std::string, std::string> cases[] = {
      // Range: a closed range says it, a one-sided bound says the bound broken.
      {"rate: 1e7", "f.yaml:1: opts.rate = 1e+07 is outside 0.1..1000 Hz"},
      {"rate: -1", "f.yaml:1: opts.rate = -1 is outside 0.1..1000 Hz"},
      {"inner: {gain: 0}", "f.yaml:1: opts.inner.gain = 0 must be > 0"},
      {"inner: {gain: 11}", "f.yaml:1: opts.inner.gain = 11 must be <= 10"},
      // Not finite, too large, not a number: the text quoted, never more than 24 characters of it.
      {"rate: .nan", "f.yaml:1: opts.rate = .nan must be a finite number"},
      {"rate: .inf", "f.yaml:1: opts.rate = .inf must be a finite number"},
      {"rate: -.Inf", "f.yaml:1: opts.rate = -.Inf must be a finite number"},
      {"rate: nan", "f.yaml:1: opts.rate = nan must be a finite number"},
      {"rate: 1e309", "f.yaml:1: opts.rate = 1e309 is too large for a number"},
      {"rate: 1" + std::string(309, '0'),
       "f.yaml:1: opts.rate = 1000000000000000... (310 characters) is too large for a number"},
      {"rate: 1" + std::string(308, '0'), "f.yaml:1: opts.rate = 1e+308 is outside 0.1..1000 Hz"},
      {"rate: fast", "f.yaml:1: opts.rate = fast must be a number"},
      {"rate: 0x10", "f.yaml:1: opts.rate = 0x10 must be a number"},
      {"rate: [1, 2]", "f.yaml:1: opts.rate must be a number, not a list"},
      {"rate: {a: 1}", "f.yaml:1: opts.rate must be a number, not a map"},
      {"rate:", "f.yaml:1: opts.rate has no value (a number is expected)"},
      // Integers.
      {"beams: 2.5", "f.yaml:1: opts.beams = 2.5 must be a whole number"},
      {"beams: 5000", "f.yaml:1: opts.beams = 5000 is outside 1..4096"},
      {"beams: 1e100", "f.yaml:1: opts.beams = 1e+100 is too large for an integer"},
      {"stamp: 99999999999999999999", "f.yaml:1: opts.stamp = 99999999999999999999 is too large for an integer"},
      {"stamp: -1", "f.yaml:1: opts.stamp = -1 is outside 0..9e+18 us"},
      {"seed: -1", "f.yaml:1: opts.seed = -1 must be >= 0"},
      {"seed: 18446744073709551616", "f.yaml:1: opts.seed = 18446744073709551616 is too large for an integer"},
      {"seed: lots", "f.yaml:1: opts.seed = lots must be a whole number"},
      // Booleans, strings, choices.
      {"loop: maybe", "f.yaml:1: opts.loop = maybe must be true or false"},
      {"loop: [true]", "f.yaml:1: opts.loop must be true or false, not a list"},
      {"channel: ''", "f.yaml:1: opts.channel must not be empty"},
      {"channel: {a: b}", "f.yaml:1: opts.channel must be a string, not a map"},
      {"channel:", "f.yaml:1: opts.channel has no value (write \"\" for an empty string)"},
      {"method: lsq", "f.yaml:1: opts.method = lsq must be icp, ndt or gicp"},
      {"shape: oval", "f.yaml:1: opts.shape = oval must be round or square"},
      // Fixed-size lists.
      {"pose: [1, 2]", "f.yaml:1: opts.pose must be a list of 3 numbers"},
      {"pose: 3", "f.yaml:1: opts.pose must be a list of 3 numbers"},
      {"pose: [1, .nan, 3]", "f.yaml:1: opts.pose[1] = .nan must be a finite number"},
      {"pose: [1, 2, 300]", "f.yaml:1: opts.pose[2] = 300 is outside -100..100 rad"},
      {"start: [1, x]", "f.yaml:1: opts.start[1] = x must be a number"},
      // Maps: the dotted key, on the line of the value.
      {"inner: 3", "f.yaml:1: opts.inner must be a map of key: value"},
      {"inner:\n  gain: 1\n  gian: 2",
       "f.yaml:3: unknown key 'opts.inner.gian': did you mean 'gain'? (known: gain, on)"},
      {"streams:\n  IMU:\n    gain: -1", "f.yaml:3: opts.streams.IMU.gain = -1 must be > 0"},
      {"streams: [IMU]", "f.yaml:1: opts.streams must be a map of CHANNEL: {gain, on}"},
      {"gain2: 0\non2: true", "f.yaml:1: opts.gain2 must be > 0 when on2"},
      {"odd: [1, 2]", "f.yaml:1: opts.odd[1] must be odd"},
      // Keys.
      {"rate: 1\nrate: 2", "f.yaml:2: opts.rate is given twice (also on line 1)"},
      {"[a]: 1", "f.yaml:1: opts: a key must be a name, not a list"},
      // A key a few edits from a known one is guessed (core/closest_name.h); one far from all is not.
      {"rat: 1",
       "f.yaml:1: unknown key 'opts.rat': did you mean 'rate'? (known: rate, beams, stamp, seed, loop, channel, "
       "method, shape, pose, start, inner, gain2, on2, streams, odd, meta)"},
      {"frequency: 1",
       "f.yaml:1: unknown key 'opts.frequency' (known: rate, beams, stamp, seed, loop, channel, method, shape, pose, "
       "start, inner, gain2, on2, streams, odd, meta)"},
  };
  for (const auto& [yaml, expected] : cases) EXPECT_EQ(error(yaml + m), expected) << yaml;
  // The document itself.
  EXPECT_EQ(table().parse(Value(YAML::Load("- 1"), "f.yaml")).error().message,
            "f.yaml:1: expected a map of key: value (rate, beams, stamp, seed, loop, channel, method, shape, pose, "
            "start, inner, gain2, on2, streams, odd, meta)");
}

TEST(ConfigTable, RendersItsReference) {
  EXPECT_EQ(inner_table().reference("x."),
            "| key | type | unit | default | range | description |\n"
            "|---|---|---|---|---|---|\n"
            "| `x.gain` | number |  | `2` | > 0 and <= 10 | how much |\n"
            "| `x.on` | bool |  | `false` |  | whether |\n");
  const std::string ref = table().reference();
  EXPECT_EQ(ref.rfind("Options for the test.\n\n| key |", 0), 0u) << ref;
  for (const char* row : {
           "| `rate` | number | Hz | `50` | 0.1..1000 | output rate |\n",
           "| `seed` | integer |  | `1` | >= 0 | random seed |\n",
           "| `channel` | string |  | `SCAN` | not empty | where from |\n",
           "| `method` | choice |  | `ndt` | icp, ndt or gicp | registration |\n",
           "| `shape` | choice |  | `round` | round or square | the footprint |\n",
           "| `pose` | [3 numbers] | m, m, rad | `[0, 0, 0]` | -100..100 | x, y, yaw |\n",
           "| `start` | [2 numbers] | m | `[0, 0]` | any | x, y |\n",
           "| `inner` | map |  |  |  | a sub-map |\n| `inner.gain` | number |  | `2` | > 0 and <= 10 | how much |\n",
           "| `gain2` | number |  | `2` | 0..1 | a fraction |\n",
           "| `streams` | map of CHANNEL: map |  |  |  | per channel |\n"
           "| `streams.<CHANNEL>.gain` | number |  | `2` | > 0 and <= 10 | how much |\n",
           "| `odd` | list of numbers |  | [1] | odd | odd numbers |\n",
           "| `meta` | map |  | required |  | about it |\n",
       }) {
    EXPECT_NE(ref.find(row), std::string::npos) << row << "\nin\n" << ref;
  }
  EXPECT_EQ(ref.find("meta.name"), std::string::npos) << "a brief section shows as one row";
  EXPECT_EQ(table().known_keys(),
            "rate, beams, stamp, seed, loop, channel, method, shape, pose, start, inner, gain2, on2, streams, odd, meta");
}

TEST(ConfigValue, FormatsNumbersShortAndExact) {
  EXPECT_EQ(format_number(1e7), "1e+07");
  EXPECT_EQ(format_number(0.015), "0.015");
  EXPECT_EQ(format_number(-1), "-1");
  EXPECT_EQ(format_number(1763776800), "1763776800");
  EXPECT_EQ(format_number(1e308), "1e+308");
  EXPECT_EQ(between(0, 1).text(), "0..1");
  EXPECT_EQ(above(0).text(), "> 0");
  EXPECT_EQ(at_least(1).text(), ">= 1");
  EXPECT_EQ(Range{}.text(), "any");
  EXPECT_EQ(above(0, 0.02).violation(0.5, "s"), "must be <= 0.02 s");
  EXPECT_EQ(above(0, 0.02).violation(0.01, "s"), "");
}

TEST(ConfigValue, ParsesAndLoadsYamlInOneLine) {
  auto bad = parse_yaml("a: [1, 2\n", "f.yaml");
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().message.rfind("f.yaml:2: ", 0), 0u) << bad.error().message;
  auto missing = load_yaml("/nonexistent/x.yaml", "module config");
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().message, "/nonexistent/x.yaml: cannot open the module config: No such file or directory");
  // Control characters in a key come out escaped: the message stays one line.
  EXPECT_EQ(error("\"a\\nb\": 1\nmeta: {name: x}\n").rfind("f.yaml:1: unknown key 'opts.a\\x0ab'", 0), 0u);
}

}  // namespace
}  // namespace driftlab::config
