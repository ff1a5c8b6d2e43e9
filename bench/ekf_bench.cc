// EKF predict+update cycles per second (scripts/bench ekf): the filter alone per measurement kind, and the
// DelayedEkf as the estimator module drives it, in order and with late odometry re-applied.
#include <benchmark/benchmark.h>

#include <cmath>

#include "estimator/ekf.h"

namespace {

using driftlab::Time;
using driftlab::estimator::DelayedEkf;
using driftlab::estimator::Ekf;
using driftlab::estimator::EkfNoise;
using driftlab::estimator::GyroZ;
using driftlab::estimator::Measurement;
using driftlab::estimator::PoseFix;
using driftlab::estimator::Twist;

constexpr int64_t kT0 = 1763776800000000;

/// One cycle: predict 5 ms ahead, then one update of the given kind.
void BM_Ekf_Cycle(benchmark::State& state) {
  Ekf ekf{EkfNoise{}};
  ekf.init(Time::from_us(kT0), {}, 0.5, 0.1);
  int64_t t = kT0;
  int i = 0;
  const auto kind = state.range(0);
  for (auto _ : state) {
    t += 5000;
    const double w = 0.3 * std::sin(++i * 0.01);
    Measurement m = kind == 0   ? Measurement{GyroZ{w, 0}}
                    : kind == 1 ? Measurement{Twist{0.5, w, 0, 0}}
                                : Measurement{PoseFix{{0.0025 * i, 0, 0}, 0, 0}};
    ekf.update(Time::from_us(t), m);
    benchmark::DoNotOptimize(ekf.state());
  }
  state.SetItemsProcessed(state.iterations());
  state.SetLabel(kind == 0 ? "gyro (1-D)" : kind == 1 ? "odometry twist (2-D)" : "pose (3-D)");
}
BENCHMARK(BM_Ekf_Cycle)->Arg(0)->Arg(1)->Arg(2);

/// The estimator's mix (gyro at 200 Hz, twist at 50 Hz) through DelayedEkf; with range(0) = 1 every twist comes
/// 30 ms late and is inserted into the past, re-applying the gyro samples after it.
void BM_DelayedEkf_Mix(benchmark::State& state) {
  DelayedEkf ekf(EkfNoise{}, 0.5);
  ekf.init(Time::from_us(kT0), {}, 0.5, 0.1);
  const bool late = state.range(0) == 1;
  int64_t i = 0;
  for (auto _ : state) {
    ++i;
    const int64_t t = kT0 + i * 5000;
    const double w = 0.3 * std::sin(static_cast<double>(i) * 0.01);
    ekf.add(Time::from_us(t), GyroZ{w, 0});
    if (i % 4 == 0) {
      const int64_t stamp = late ? t - 30000 : t;
      ekf.add(Time::from_us(stamp), Twist{0.5, w, 0, 0});
    }
  }
  state.SetItemsProcessed(state.iterations() + state.iterations() / 4);
  state.SetLabel(late ? "twist 30 ms late" : "in order");
}
BENCHMARK(BM_DelayedEkf_Mix)->Arg(0)->Arg(1);

}  // namespace

BENCHMARK_MAIN();
