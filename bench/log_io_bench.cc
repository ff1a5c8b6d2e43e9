// Log I/O throughput: driftlab's LogWriter/LogReader against LCM's C event-log API
// (lcm_eventlog_write_event / lcm_eventlog_read_next_event) on the same data, in the page cache.
// Files go to $DRIFTLAB_BENCH_DIR (default /dev/shm, a tmpfs: pure page cache). Run through scripts/bench,
// which prints the ratios.
#include <benchmark/benchmark.h>
#include <lcm/eventlog.h>
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>

#include <cstdio>
#include <cstring>
#include <cstdlib>
#include <string>
#include <vector>

#include "core/log_reader.h"
#include "core/log_writer.h"

namespace {

std::string bench_path(const std::string& name) {
  const char* dir = std::getenv("DRIFTLAB_BENCH_DIR");
  return std::string(dir != nullptr ? dir : "/dev/shm") + "/driftlab-bench-" + std::to_string(getpid()) + "-" + name;
}

/// Events per iteration for a payload size: about 25 MB (small) or 200 MB (large) of log.
int64_t events_for(int64_t size) { return size <= 4096 ? 250000 : 200; }

std::vector<uint8_t> payload(int64_t size) {
  std::vector<uint8_t> p(static_cast<size_t>(size));
  for (size_t i = 0; i < p.size(); ++i) p[i] = static_cast<uint8_t>(i * 131 + 7);
  return p;
}

const char* kChannels[] = {"IMU", "SCAN", "ODOM", "GROUND_TRUTH"};

void write_lcm(const std::string& path, int64_t n, const std::vector<uint8_t>& data) {
  lcm_eventlog_t* log = lcm_eventlog_create(path.c_str(), "w");
  if (log == nullptr) std::abort();
  for (int64_t i = 0; i < n; ++i) {
    lcm_eventlog_event_t ev{};
    ev.timestamp = 1700000000000000 + i * 100;
    ev.channel = const_cast<char*>(kChannels[i % 4]);
    ev.channellen = static_cast<int32_t>(std::strlen(ev.channel));
    ev.datalen = static_cast<int32_t>(data.size());
    ev.data = const_cast<uint8_t*>(data.data());
    if (lcm_eventlog_write_event(log, &ev) != 0) std::abort();
  }
  lcm_eventlog_destroy(log);
}

void write_driftlab(const std::string& path, int64_t n, const std::vector<uint8_t>& data) {
  auto w = driftlab::LogWriter::create(path);
  if (!w.ok()) std::abort();
  for (int64_t i = 0; i < n; ++i) {
    if (!w->write(1700000000000000 + i * 100, kChannels[i % 4], data).ok()) std::abort();
  }
  if (!w->close().ok()) std::abort();
}

void finish(benchmark::State& state, int64_t n, int64_t size) {
  state.SetItemsProcessed(state.iterations() * n);
  state.SetBytesProcessed(state.iterations() * n * size);
}

void BM_Write_Lcm(benchmark::State& state) {
  const int64_t size = state.range(0), n = events_for(size);
  const auto data = payload(size);
  const std::string path = bench_path("write-lcm");
  for (auto _ : state) write_lcm(path, n, data);
  std::remove(path.c_str());
  finish(state, n, size);
}

void BM_Write_Driftlab(benchmark::State& state) {
  const int64_t size = state.range(0), n = events_for(size);
  const auto data = payload(size);
  const std::string path = bench_path("write-driftlab");
  for (auto _ : state) write_driftlab(path, n, data);
  std::remove(path.c_str());
  finish(state, n, size);
}

/// The floor for any writer: write(2) of the finished log bytes, 1 MiB at a time, into a fresh file.
/// Whatever a writer does in user space, it cannot beat the kernel's copy into the page cache.
void BM_Write_Floor(benchmark::State& state) {
  const int64_t size = state.range(0), n = events_for(size);
  const std::string path = bench_path("write-floor");
  write_lcm(path, n, payload(size));
  std::vector<uint8_t> bytes(std::filesystem::file_size(path));
  {
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (std::fread(bytes.data(), 1, bytes.size(), f) != bytes.size()) std::abort();
    std::fclose(f);
  }
  for (auto _ : state) {
    const int fd = open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    for (size_t at = 0; at < bytes.size(); at += 1 << 20) {
      const size_t chunk = std::min<size_t>(1 << 20, bytes.size() - at);
      if (write(fd, bytes.data() + at, chunk) != static_cast<ssize_t>(chunk)) std::abort();
    }
    close(fd);
  }
  std::remove(path.c_str());
  finish(state, n, size);
}

/// Both readers consume each event the same way: they look at its channel and at every 4 KiB of its data.
inline uint64_t consume(const char* channel, const uint8_t* data, size_t size) {
  uint64_t sum = static_cast<uint8_t>(channel[0]);
  for (size_t i = 0; i < size; i += 4096) sum += data[i];
  return sum;
}

void BM_Read_Lcm(benchmark::State& state) {
  const int64_t size = state.range(0), n = events_for(size);
  const std::string path = bench_path("read-lcm");
  write_lcm(path, n, payload(size));
  for (auto _ : state) {
    lcm_eventlog_t* log = lcm_eventlog_create(path.c_str(), "r");
    uint64_t sum = 0;
    int64_t count = 0;
    while (lcm_eventlog_event_t* ev = lcm_eventlog_read_next_event(log)) {
      sum += consume(ev->channel, static_cast<const uint8_t*>(ev->data), static_cast<size_t>(ev->datalen));
      ++count;
      lcm_eventlog_free_event(ev);
    }
    lcm_eventlog_destroy(log);
    if (count != n) std::abort();
    benchmark::DoNotOptimize(sum);
  }
  std::remove(path.c_str());
  finish(state, n, size);
}

void BM_Read_Driftlab(benchmark::State& state) {
  const int64_t size = state.range(0), n = events_for(size);
  const std::string path = bench_path("read-driftlab");
  write_lcm(path, n, payload(size));  // the same file LCM reads
  for (auto _ : state) {
    auto reader = driftlab::LogReader::open(path);
    uint64_t sum = 0;
    int64_t count = 0;
    driftlab::Event e;
    while (reader->next(e)) {
      sum += consume(e.channel.data(), e.data.data(), e.data.size());
      ++count;
    }
    if (count != n) std::abort();
    benchmark::DoNotOptimize(sum);
  }
  std::remove(path.c_str());
  finish(state, n, size);
}

}  // namespace

BENCHMARK(BM_Write_Lcm)->Arg(100)->Arg(1 << 20)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_Write_Driftlab)->Arg(100)->Arg(1 << 20)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_Write_Floor)->Arg(100)->Arg(1 << 20)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_Read_Lcm)->Arg(100)->Arg(1 << 20)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_Read_Driftlab)->Arg(100)->Arg(1 << 20)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK_MAIN();
