// libFuzzer target: any bytes given to LogReader and LogIndex must neither crash nor yield an event outside
// the input, and reading must always make progress. Each event is also walked by a message schema (as
// `driftlab export csv` does): its own type's when known, and one picked by its last byte, so every definition
// meets arbitrary bytes.
#include <cstdint>
#include <cstdlib>
#include <span>

#include "core/log_index.h"
#include "core/log_format.h"
#include "core/log_reader.h"
#include "lcmtypes/schema.h"
#include "lcmtypes/type_registry.h"

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
