// libFuzzer target: any bytes given to LogReader and LogIndex must neither crash nor yield an event outside
// the input, and reading must always make progress. Each event is also walked by a message schema (as
// `driftlab export csv` does): its own type's when known, and one picked by its last byte, so every definition
// meets arbitrary bytes, and checked against its type's layout (lcmtypes/validate.h): what passes must decode with
// lcm-gen's own decoder without throwing.
#include <cstdint>
#include <cstdlib>
#include <span>

#include "core/log_index.h"
#include "core/log_format.h"
#include "core/log_reader.h"
#include "driftlab/image_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/point_cloud_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "lcmtypes/schema.h"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/type_registry.h"
#include "lcmtypes/validate.h"

namespace {

/// What the layout check promises: a message it passes decodes with lcm-gen's own decoder, without throwing
/// (an exception here ends the fuzzer: a hole in the check), consuming exactly its bytes.
template <typename T>
void decode_if_well_formed(std::span<const uint8_t> data) {
  if (!driftlab::lcmtypes::well_formed(data, T::getHash())) return;
  T m;
  if (m.decode(data.data(), 0, static_cast<int>(data.size())) != static_cast<int>(data.size())) std::abort();
}

void check_payload(std::span<const uint8_t> data) {
  const auto problem = driftlab::lcmtypes::layout_problem(data);
  const int64_t fp = driftlab::logfmt::fingerprint(data);
  if (!problem && driftlab::lcmtypes::type_name(fp) != nullptr && !driftlab::lcmtypes::well_formed(data, fp)) {
    std::abort();  // the two entry points disagree
  }
  decode_if_well_formed<driftlab::laser_scan_t>(data);
  decode_if_well_formed<driftlab::tf_t>(data);
  decode_if_well_formed<driftlab::imu_t>(data);
  decode_if_well_formed<driftlab::odometry_t>(data);
  decode_if_well_formed<driftlab::pose_t>(data);
  decode_if_well_formed<driftlab::image_t>(data);
  decode_if_well_formed<driftlab::point_cloud_t>(data);
  (void)driftlab::lcmtypes::read_header(data, 0);
  (void)driftlab::lcmtypes::read_motion(data);
  (void)driftlab::lcmtypes::ready_after_us(data);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::span<const uint8_t> bytes(data, size);
  uint64_t problems = 0;
  auto reader = driftlab::LogReader::from_memory(bytes, {.on_problem = [&](const driftlab::Problem& p) {
                                                           if (p.offset > size) std::abort();
                                                           ++problems;
                                                         }});
  if (!reader.ok()) std::abort();
  driftlab::Event e;
  uint64_t last_offset = 0;
  int64_t events = 0, first_utime = 0;
  bool first = true;
  while (reader->next(e)) {
    const auto* begin = e.data.data();
    if (e.offset >= size || (!first && e.offset <= last_offset)) std::abort();
    if (e.channel.empty() || begin < data || begin + e.data.size() > data + size) std::abort();
    if (reinterpret_cast<const uint8_t*>(e.channel.data()) + e.channel.size() != begin) std::abort();
    const auto& structs = driftlab::lcmtypes::all_structs();
    const auto ignore = [](const std::string&, const std::string&) {};
    if (const char* type = driftlab::lcmtypes::type_name(driftlab::logfmt::fingerprint(e.data))) {
      driftlab::lcmtypes::flatten(*driftlab::lcmtypes::find_struct(type), e.data, ignore);
    }
    if (!e.data.empty()) driftlab::lcmtypes::flatten(structs[e.data.back() % structs.size()], e.data, ignore, {.bytes = true});
    check_payload(e.data);
    if (first) first_utime = e.utime;
    last_offset = e.offset;
    first = false;
    ++events;
  }
  const auto index = driftlab::LogIndex::build(bytes);
  if (index.summary().events != events || index.summary().problems_total != reader->problems()) std::abort();
  if (events > 0) {
    if (!reader->seek(first_utime).ok() || !reader->next(e)) std::abort();
  }
  return 0;
}
