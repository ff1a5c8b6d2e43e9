// 3D point-cloud odometry (slam/slam3d.h) per registration method (scripts/bench slam3d): clouds per second and
// the real-time factor of the module alone, on a simulated session of the 16 x 1800 lidar (sim/scenarios/
// indoor_3d.yaml) held in memory and played in arrival order through the module host (runtime/module_host.h,
// as on replay: routing, message checks), so log reading is not in the figure. Each run also reports the path's error
// against ground truth (first pose aligned).
//   slam3d_bench [--log=SESSION.lcm | --seconds=N] [benchmark flags]
// Without --log, N simulated seconds (default 20) are made in $DRIFTLAB_BENCH_DIR (default /dev/shm) first.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "analyzers/trajectory.h"
#include "core/install_layout.h"
#include "core/log_reader.h"
#include "core/time.h"
#include "driftlab/pose_t.hpp"
#include "runtime/bus.h"
#include "runtime/module_host.h"
#include "sim/scenario.h"
#include "sim/simulator.h"
#include "slam/slam3d.h"

namespace {

using namespace driftlab;

struct OwnedEvent {
  std::string channel;
  int64_t utime;
  std::vector<uint8_t> data;
};
std::vector<OwnedEvent> g_events;  ///< POINTS, ODOM, TF_STATIC in arrival order
analyzers::Trajectory g_truth;
double g_span_s = 0;
int64_t g_clouds = 0;

double ate_first_pose(const analyzers::Trajectory& est) {
  analyzers::Matched m = analyzers::match_nearest(g_truth, est, 0.006, 0);
  if (m.est.size() == 0) return NAN;
  analyzers::Alignment a;
  a.type = analyzers::AlignmentType::kSe3;
  a.rotation = (m.ref.orientations[0] * m.est.orientations[0].conjugate()).toRotationMatrix();
  a.translation = m.ref.positions[0] - a.rotation * m.est.positions[0];
  m.est = analyzers::apply(a, std::move(m.est));
  return analyzers::ape(m).trans.rmse;
}

void BM_Slam3d(benchmark::State& state, const std::string& yaml) {
  double ate = NAN;
  ModuleCounters counters;
  for (auto _ : state) {
    auto module = slam::make_slam3d(YAML::Load(yaml), "bench");
    if (!module) return state.SkipWithError(module.error().message.c_str());
    const Module& slam = **module;
    runtime::ModuleHost host({.stats_period_s = 0});
    host.add_module(std::move(*module));
    analyzers::Trajectory path;
    host.set_outlet([&path](const BusMessage& m) {
      driftlab::pose_t p;
      if (m.channel != "SLAM_POSE" || p.decode(m.data.data(), 0, static_cast<int>(m.data.size())) < 0) return;
      path.push_back(Time::from_us(p.header.utime).seconds(), {p.position.x, p.position.y, p.position.z},
                     Eigen::Quaterniond(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z));
    });
    if (!host.start()) return state.SkipWithError("start failed");
    for (const OwnedEvent& e : g_events) {
      if (!host.advance(Time::from_us(e.utime)) || !host.deliver(e.channel, e.data)) {
        return state.SkipWithError("delivery failed");
      }
    }
    if (!host.finish()) return state.SkipWithError("finish failed");
    state.PauseTiming();
    ate = ate_first_pose(path);
    counters = slam.counters();
    state.ResumeTiming();
  }
  state.SetItemsProcessed(state.iterations() * g_clouds);  // items_per_second = clouds/s
  state.counters["x_real_time"] =
      benchmark::Counter(g_span_s * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["ate_m"] = ate;
  state.counters["dropped"] = static_cast<double>(counters.dropped);
  for (const auto& [name, value] : counters.metrics) {
    if (name == "unusable" || name == "unconverged" || name == "rejected" || name == "keyframes" ||
        name == "max_fitness_m2") {
      state.counters[name] = value;
    }
  }
}

int load(const std::string& path) {
  auto reader = LogReader::open(path, {.channels = "POINTS|ODOM|TF_STATIC|GROUND_TRUTH"});
  if (!reader) {
    std::fprintf(stderr, "slam3d_bench: %s\n", reader.error().message.c_str());
    return 2;
  }
  Event e;
  int64_t first = -1, last = 0;
  while (reader->next(e)) {
    if (e.channel == "GROUND_TRUTH") {
      driftlab::pose_t p;
      if (p.decode(e.data.data(), 0, static_cast<int>(e.data.size())) < 0) continue;
      g_truth.push_back(Time::from_us(p.header.utime).seconds(), {p.position.x, p.position.y, p.position.z},
                        Eigen::Quaterniond(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z));
      continue;
    }
    if (first < 0) first = e.utime;
    last = e.utime;
    g_clouds += e.channel == "POINTS";
    g_events.push_back({std::string(e.channel), e.utime, {e.data.begin(), e.data.end()}});
  }
  g_span_s = (Time::from_us(last) - Time::from_us(first)).seconds();
  if (g_clouds == 0) {
    std::fprintf(stderr, "slam3d_bench: no POINTS in %s\n", path.c_str());
    return 2;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  std::string log;
  double seconds = 20;
  for (int i = 1; i < argc; ++i) {
    if (std::strncmp(argv[i], "--log=", 6) == 0) {
      log = argv[i] + 6;
    } else if (std::strncmp(argv[i], "--seconds=", 10) == 0) {
      seconds = std::atof(argv[i] + 10);
    } else {
      std::fprintf(stderr, "slam3d_bench: unknown argument %s\n", argv[i]);
      return 2;
    }
  }
  std::string made;
  if (log.empty()) {
    const char* dir = std::getenv("DRIFTLAB_BENCH_DIR");
    made = std::string(dir != nullptr ? dir : "/dev/shm") + "/slam3d_bench." + std::to_string(getpid()) + ".lcm";
    auto scenario = sim::load_scenario(data_path("scenarios/indoor_3d.yaml").string());
    if (!scenario) return std::fprintf(stderr, "slam3d_bench: %s\n", scenario.error().message.c_str()), 2;
    scenario->duration = seconds;
    auto simulation = sim::Simulation::create(*scenario);
    if (!simulation) return std::fprintf(stderr, "slam3d_bench: %s\n", simulation.error().message.c_str()), 2;
    sim::SimOptions options;
    options.out = made;
    auto report = (*simulation)->run(options);
    if (!report) return std::fprintf(stderr, "slam3d_bench: %s\n", report.error().message.c_str()), 2;
    log = made;
  }
  const int rc = load(log);
  if (!made.empty()) {
    std::error_code ec;
    std::filesystem::remove(made, ec);
    std::filesystem::remove(made + ".faults.json", ec);
  }
  if (rc != 0) return rc;
  for (const char* method : {"ndt", "icp", "gicp"}) {
    benchmark::RegisterBenchmark((std::string("Slam3d/") + method).c_str(), BM_Slam3d, std::string("method: ") + method)
        ->Unit(benchmark::kMillisecond);
  }
  benchmark::RegisterBenchmark("Slam3d/ndt_voxel_0.2", BM_Slam3d, std::string("method: ndt\nvoxel: 0.2\n"))
      ->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("Slam3d/ndt_no_deskew", BM_Slam3d, std::string("method: ndt\ndeskew: false\n"))
      ->Unit(benchmark::kMillisecond);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
