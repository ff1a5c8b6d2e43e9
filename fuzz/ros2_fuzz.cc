// Fuzzes the ROS 2 readers: the MCAP container (records, chunks with their compression and CRCs, summary), the
// rosbag2 sqlite3 storage, and ROS message definitions with the messages walked by them in CDR and ROS 1
// serialization. Whatever they deliver must be well formed: mapped messages a valid driftlab message, walks a
// JSON text or a reason; an MCAP file read pipelined (a second thread decompresses and checks its chunks) must give
// the same calls as read on one thread.
// Input: a selector byte, then the bytes for the reader it selects.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <span>
#include <string>

#include "formats/mcap.h"
#include "formats/ros2_bag.h"
#include "formats/ros_definition.h"
#include "formats/ros_messages.h"
#include "fuzz/structure_mutators.h"
#include "lcmtypes/validate.h"

namespace {

using namespace driftlab::formats;

void check(std::span<const uint8_t> lcm) {
  if (driftlab::lcmtypes::layout_problem(lcm)) std::abort();
}

/// A message as the importer treats it: a mapped type converted, any other walked by its schema.
void consume(std::string_view type, std::string_view encoding, std::string_view schema_encoding,
             std::string_view schema, std::span<const uint8_t> payload) {
  const Serialization s = encoding == "ros1" ? Serialization::kRos1 : Serialization::kCdr;
  std::string error;
  if (driftlab_type_for(type)) {
    if (auto c = convert_ros_message(type, s, payload, 0, 0, &error)) check(c->lcm);
    return;
  }
  if (schema_encoding != "ros2msg" && schema_encoding != "ros1msg") return;
  auto d = RosDefinition::parse(type, schema, s);
  if (!d) return;
  (void)d->check(payload);
  auto j = d->to_json(payload);
  if (j && j->empty()) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const uint8_t selector = data[0];
  std::span<const uint8_t> rest(data + 1, size - 1);
  if (selector < 128) {
    // An MCAP file: the magic is given, so the fuzzer spends its time on the records.
    std::string bytes = "\x89MCAP0\r\n";
    bytes.append(reinterpret_cast<const char*>(rest.data()), rest.size());
    // Read twice: pipelined (chunks decompressed and checked on the reader's second thread) and on this thread
    // alone; the two must make the same calls in the same order.
    std::string trace[2];
    for (const bool pipelined : {true, false}) {
      auto r = McapReader::from_memory({reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()});
      if (!r) std::abort();
      r->set_pipelined(pipelined);
      std::string& t = trace[pipelined ? 1 : 0];
      r->read(
          [&](const McapMessage& m) {
            t += "m" + std::to_string(m.channel->id) + " " + std::to_string(m.sequence) + " " +
                 std::to_string(m.log_time) + " " + std::to_string(m.offset) + " " + std::to_string(m.offset_in_chunk) +
                 " ";
            t.append(reinterpret_cast<const char*>(m.data.data()), m.data.size());
            t += '\n';
            if (!pipelined) return;
            const McapSchema* s = m.channel->schema;
            consume(s ? std::string_view(s->name) : "", m.channel->message_encoding,
                    s ? std::string_view(s->encoding) : "", s ? std::string_view(s->data) : "", m.data);
          },
          [&](const McapProblem& p) { t += "p" + std::to_string(p.offset) + " " + p.what + "\n"; },
          [&](const McapMetadata& md) { t += "d" + md.name + "\n"; });
      if (r->statistics()) t += "s" + std::to_string(r->statistics()->message_count);
    }
    if (trace[0] != trace[1]) std::abort();
  } else if (selector < 160) {
    auto r = SqliteBagReader::from_memory(rest);
    if (!r) return 0;
    r->read(
        [&](const Ros2DbMessage& m) {
          auto d = r->definitions().find(m.topic->type);
          consume(m.topic->type, m.topic->serialization_format, d != r->definitions().end() ? d->second.first : "",
                  d != r->definitions().end() ? d->second.second : "", m.data);
        },
        [](const Ros2DbProblem&) {});
  } else {
    // A definition (up to the first NUL), then a message of it.
    const std::string_view all(reinterpret_cast<const char*>(rest.data()), rest.size());
    const size_t nul = all.find('\0');
    if (nul == std::string_view::npos) return 0;
    const auto payload = rest.subspan(nul + 1);
    consume("fuzz_msgs/msg/Root", (selector & 1) ? "ros1" : "cdr", (selector & 1) ? "ros1msg" : "ros2msg",
            all.substr(0, nul), payload);
  }
  return 0;
}

extern "C" size_t LLVMFuzzerMutate(uint8_t* data, size_t size, size_t max_size);

// Half the mutations rewrite the input's structure (fuzz/structure_mutators.h): an MCAP file's chunk (lying
// declared sizes, zeros appended behind them, the CRC cleared, another codec), or a definition replaced by one of
// nested, cyclic or repeated types (the message after it kept). The rest, and anything else, libFuzzer's.
extern "C" size_t LLVMFuzzerCustomMutator(uint8_t* data, size_t size, size_t max_size, unsigned int seed) {
  using namespace driftlab::fuzz;
  Rng rng(seed);
  if (size >= 1 && max_size > 1 && pick(rng, 2) == 0) {
    std::vector<uint8_t> out;
    if (data[0] < 128 && mutate_mcap(rng, {data + 1, size - 1}, max_size - 1, out)) {
      std::memcpy(data + 1, out.data(), out.size());
      return out.size() + 1;
    }
    if (data[0] >= 160) {
      const std::string_view all(reinterpret_cast<const char*>(data + 1), size - 1);
      const size_t nul = all.find('\0');
      const std::string payload(nul == std::string_view::npos ? std::string_view() : all.substr(nul + 1));
      if (payload.size() + 2 < max_size) {
        const std::string d = nested_definition(rng, max_size - payload.size() - 2);
        if (d.size() + payload.size() + 2 <= max_size) {
          std::memcpy(data + 1, d.data(), d.size());
          data[1 + d.size()] = 0;
          std::memcpy(data + 2 + d.size(), payload.data(), payload.size());
          return d.size() + payload.size() + 2;
        }
      }
    }
  }
  return LLVMFuzzerMutate(data, size, max_size);
}
