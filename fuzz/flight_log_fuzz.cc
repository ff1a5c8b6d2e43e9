// Fuzzes the flight-log diagnosis (analyzers/flight_log.h): a hostile PX4 flight log, imported as `driftlab import`
// imports it, then diagnosed, and its UTC read (flight_utc). The diagnosis reads each topic by field name through
// the formats the import stored, so hostile formats, messages cut short, hostile stamps and offsets all reach it.
// Input: a ULog file (from its magic). Whatever it is, the diagnosis must hold its own invariants: shares within
// [0, 1], counts not negative, the timeline in time order.
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <string>

#include "analyzers/flight_log.h"
#include "formats/import.h"

namespace {

/// A scratch folder of this process, made once.
const std::string& scratch() {
  static const std::string dir = [] {
    char name[] = "/tmp/flight_log_fuzz.XXXXXX";
    if (mkdtemp(name) == nullptr) std::abort();
    return std::string(name);
  }();
  return dir;
}

bool share(double x) { return x >= 0 && x <= 1; }

void check(const driftlab::analyzers::FlightLogDiagnosis& d) {
  if (d.dropout_count < 0 || d.dropout_total_s < 0 || d.dropout_max_s > d.dropout_total_s + 1e-9) std::abort();
  for (const auto& i : d.imu) {
    if (!share(i.share_1x) || !share(i.share_2x) || !share(i.share_0) || !share(i.share_other)) std::abort();
    if (std::abs(i.share_1x + i.share_2x + i.share_0 + i.share_other - 1) > 1e-9 || i.gaps < 0) std::abort();
  }
  for (const auto& s : d.sample_delays) {
    if (s.count <= 0 || s.negative < 0 || s.negative > s.count || !(s.p50_s <= s.p99_s) || !(s.p99_s <= s.max_s)) {
      std::abort();
    }
  }
  for (const auto& e : d.estimator) {
    if (e.over < 0 || e.over > e.samples || e.time_over_s < 0) std::abort();
  }
  for (size_t i = 1; i < d.timeline.size(); ++i) {
    if (d.timeline[i].start_s < d.timeline[i - 1].start_s) std::abort();
  }
  for (const auto& p : d.problems) {
    if (p.empty()) std::abort();
  }
  if (d.utc.known && (d.utc.fixes <= 0 || d.utc.spread_s < 0)) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string ulg = scratch() + "/in.ulg", lcm = scratch() + "/out.lcm";
  {
    std::ofstream f(ulg, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  std::remove(lcm.c_str());
  auto imported = driftlab::formats::import_log(ulg, lcm, [](const std::string&) {});
  if (!imported) return 0;  // not a ULog, or one that cannot be read at all: nothing written
  auto d = driftlab::analyzers::diagnose_flight_log(lcm);
  if (!d) return 0;
  check(*d);
  return 0;
}
