// core/quantile.h against numpy's np.quantile (its default method, "linear") run by Debian's Python: the same
// number, to the last bit, on arrays of odd and even lengths, with duplicates, of one value, of doubles and of
// int64 stamps, at the quantiles driftlab reports (and the ends).
#include "core/quantile.h"

#include <gtest/gtest.h>

#include <cinttypes>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "tests/test_util.h"

namespace driftlab {
namespace {

constexpr double kQs[] = {0.0, 0.01, 0.1, 0.5, 0.95, 0.99, 1.0};

/// Reads lines "Q V1 V2 ..." (doubles) or "Q i V1 V2 ..." (int64) and prints repr(np.quantile(V, Q)) for each.
constexpr const char* kNumpy = R"(
import sys, numpy as np
for line in open(sys.argv[1]):
    f = line.split()
    q = float(f[0])
    v = np.array([int(a) for a in f[2:]], dtype=np.int64) if f[1] == "i" else np.array([float(a) for a in f[1:]])
    print(repr(float(np.quantile(v, q))))
)";

struct Case {
  std::string line;  ///< the input line for the script
  double ours;       ///< core/quantile.h's answer
};

std::string exact(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

void add_cases(const std::vector<double>& v, std::vector<Case>& cases) {
  for (double q : kQs) {
    std::vector<double> copy = v;  // quantile_in_place reorders
    std::string line = exact(q);
    for (double x : v) line += " " + exact(x);
    cases.push_back({line, quantile_in_place(copy, q)});
    RunningQuantile<double> running(q);  // the same values one at a time, held to numpy too
    for (double x : v) running.add(x);
    cases.push_back({line, running.value()});
  }
}

void add_cases(const std::vector<int64_t>& v, std::vector<Case>& cases) {
  for (double q : kQs) {
    std::vector<int64_t> copy = v;
    std::string line = exact(q) + " i";
    for (int64_t x : v) line += " " + std::to_string(x);
    cases.push_back({line, quantile_in_place(copy, q)});
  }
}

TEST(Quantile, EqualsNumpysDefaultToTheLastBit) {
  std::vector<Case> cases;
  add_cases(std::vector<double>{3, 1, 2}, cases);                 // odd
  add_cases(std::vector<double>{4, 1, 3, 2}, cases);              // even
  add_cases(std::vector<double>{2, 2, 1, 5, 2, 1, 5, 5}, cases);  // duplicates
  add_cases(std::vector<double>{7, 7, 7}, cases);                 // one value
  add_cases(std::vector<double>{42.5}, cases);                    // one sample
  add_cases(std::vector<double>{0.1, -3.3, 2.2, 1e-3, 7.77, -0.5, 1e6, 0.1, 2.2}, cases);
  uint64_t x = 88172645463325252ull;
  auto next = [&x] {
    x ^= x << 13, x ^= x >> 7, x ^= x << 17;
    return static_cast<double>(x >> 11) / 9007199254740992.0 * 200 - 100;  // [-100, 100)
  };
  for (size_t n : {2, 3, 10, 11, 100, 101}) {
    for (int rep = 0; rep < 5; ++rep) {
      std::vector<double> v(n);
      for (double& e : v) e = next();
      add_cases(v, cases);
    }
  }
  // Header stamps in microseconds of the epoch, as the diagnosis takes their median.
  add_cases(std::vector<int64_t>{1764000000123457, 1764000000100001, 1764000000200003, 1764000000150002}, cases);
  add_cases(std::vector<int64_t>{1764000000123457, 1764000000100001, 1764000000200003}, cases);

  test::TempDir dir;
  {
    std::ofstream in(dir.file("in.txt"));
    for (const Case& c : cases) in << c.line << "\n";
    std::ofstream(dir.file("numpy_quantile.py")) << kNumpy;
  }
  const auto r =
      test::run_capture(std::string(DRIFTLAB_PYTHON) + " " + dir.file("numpy_quantile.py") + " " + dir.file("in.txt"));
  ASSERT_EQ(r.code, 0) << r.err;
  std::istringstream out(r.out);
  size_t i = 0, differ = 0;
  for (std::string line; std::getline(out, line); ++i) {
    ASSERT_LT(i, cases.size());
    const double numpy = std::strtod(line.c_str(), nullptr);
    if (numpy != cases[i].ours) {
      ++differ;
      ADD_FAILURE() << "np.quantile " << line << ", core/quantile.h " << exact(cases[i].ours) << " for q and values "
                    << cases[i].line;
    }
  }
  EXPECT_EQ(i, cases.size());
  EXPECT_EQ(differ, 0u);
}

TEST(Quantile, IsNanOnNothing) {
  std::vector<double> none;
  EXPECT_TRUE(std::isnan(quantile_in_place(none, 0.5)));
  EXPECT_TRUE(std::isnan(RunningQuantile<double>(0.5).value()));
}

// A running quantile asked after every value (as the 2D SLAM asks for its heading checks' 90th percentile at each
// statistics message) gives what a selection over all the values so far gives, to the last bit: values in random
// order, ascending, descending and with many repeats, at the quantiles the project reports and the ends.
TEST(Quantile, RunningQuantileIsTheSelectionAfterEveryValue) {
  uint64_t x = 2463534242ull;
  auto next = [&x] {
    x ^= x << 13, x ^= x >> 7, x ^= x << 17;
    return static_cast<float>(x % 1000) / 10.f;  // repeats
  };
  size_t asked = 0;
  for (const double q : {0.0, 0.05, 0.5, 0.9, 0.95, 0.99, 1.0}) {
    for (int order = 0; order < 3; ++order) {
      RunningQuantile<float> running(q);
      std::vector<float> all;
      for (int k = 0; k < 700; ++k) {
        // Random with repeats; ascending, each value three times; descending.
        const float v = order == 0   ? next()
                        : order == 1 ? std::floor(static_cast<float>(k) / 3)
                                     : static_cast<float>(-k);
        running.add(v), all.push_back(v);
        std::vector<float> copy = all;
        ASSERT_EQ(running.value(), quantile_in_place(copy, q))
            << "q " << q << " order " << order << " n " << all.size();
        ASSERT_EQ(running.size(), all.size());
        ++asked;
      }
    }
  }
  EXPECT_EQ(asked, 7u * 3 * 700);
}

}  // namespace
}  // namespace driftlab
