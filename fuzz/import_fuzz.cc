// Fuzzes the importers' readers: the ROS 1 bag container (records, chunks, compression), CARMEN lines, the ROS
// message decoders in both serializations, and PX4's ULog (records, formats, the PX4 topics' mappings). Whatever
// they deliver must be a well-formed driftlab message.
// Input: a selector byte, then the bytes for the reader it selects: 0..63 a bag after its magic, 64..95 CARMEN
// text, 96..191 a ROS message (its type and serialization from the selector), 192..255 a ULog file (from its magic).
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include "formats/carmen.h"
#include "formats/ros1_bag.h"
#include "formats/ros_messages.h"
#include "formats/ulog.h"
#include "formats/ulog_messages.h"
#include "fuzz/structure_mutators.h"
#include "lcmtypes/validate.h"

namespace {

constexpr const char* kTypes[] = {"sensor_msgs/LaserScan",
                                  "sensor_msgs/Imu",
                                  "sensor_msgs/PointCloud2",
                                  "sensor_msgs/Image",
                                  "sensor_msgs/CompressedImage",
                                  "sensor_msgs/JointState",
                                  "nav_msgs/Odometry",
                                  "geometry_msgs/PoseStamped",
                                  "geometry_msgs/PoseWithCovarianceStamped",
                                  "geometry_msgs/TransformStamped",
                                  "geometry_msgs/TwistStamped",
                                  "geometry_msgs/Twist",
                                  "tf2_msgs/TFMessage",
                                  "sensor_msgs/NavSatFix",
                                  "sensor_msgs/MagneticField",
                                  "sensor_msgs/FluidPressure"};
constexpr size_t kNumTypes = sizeof(kTypes) / sizeof(kTypes[0]);

void check(std::span<const uint8_t> lcm) {
  if (driftlab::lcmtypes::layout_problem(lcm)) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const uint8_t selector = data[0];
  std::span<const uint8_t> rest(data + 1, size - 1);
  using namespace driftlab::formats;
  if (selector < 64) {
    // A bag: the magic is given, so the fuzzer spends its time on the records.
    std::string bytes = "#ROSBAG V2.0\n";
    bytes.append(reinterpret_cast<const char*>(rest.data()), rest.size());
    // Read twice: pipelined (chunks decompressed ahead on the reader's threads) and on this thread alone; the
    // calls must be the same.
    std::string trace[2];
    for (const bool pipelined : {true, false}) {
      auto bag = Ros1BagReader::from_memory({reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()});
      if (!bag) std::abort();
      bag->set_pipelined(pipelined);
      std::string& t = trace[pipelined ? 1 : 0];
      std::string error;
      bag->read(
          [&](const BagMessage& m) {
            t += "m " + std::to_string(m.offset) + " " + std::to_string(m.record_time_ns) + " " +
                 std::to_string(m.data.size()) + "\n";
            if (!pipelined) return;
            if (auto c = convert_ros_message(m.connection->type, Serialization::kRos1, m.data, 0, 0, &error)) {
              check(c->lcm);
            }
          },
          [&](const BagProblem& p) { t += "p " + std::to_string(p.offset) + " " + p.what + "\n"; });
    }
    if (trace[0] != trace[1]) std::abort();
  } else if (selector < 96) {
    auto log = CarmenReader::from_text(std::string(reinterpret_cast<const char*>(rest.data()), rest.size()));
    log.read([](const CarmenMessage& m) { check(m.lcm); }, [](size_t, const std::string&) {});
  } else if (selector >= 192) {
    auto log = UlogReader::from_memory(std::vector<uint8_t>(rest.begin(), rest.end()));
    if (!log) return 0;
    UlogReader::Callbacks cb;
    int64_t seq = 0;
    cb.data = [&](const UlogData& d) {
      const UlogLayout* l = d.subscription->layout.get();
      if (!l) return;
      if (d.payload.size() < l->size_written || d.payload.size() > l->size) std::abort();  // checked by the reader
      if (auto c = convert_ulog_message(*l, d.payload, d.timestamp, seq++)) check(c->lcm);
    };
    // Read twice: the same file gives the same calls (the importer's first pass names the channels).
    std::string trace[2];
    for (std::string& t : trace) {
      cb.problem = [&](uint64_t offset, const std::string& what) { t += std::to_string(offset) + " " + what + "\n"; };
      cb.logged = [&](const UlogLogged& m) { t += "l " + std::to_string(m.offset) + "\n"; };
      (void)log->read(cb);
    }
    if (trace[0] != trace[1]) std::abort();
  } else {
    const char* type = kTypes[selector % kNumTypes];
    const auto s = (selector & 1) ? Serialization::kCdr : Serialization::kRos1;
    std::string error;
    if (auto c = convert_ros_message(type, s, rest, 0, 0, &error)) check(c->lcm);
  }
  return 0;
}

extern "C" size_t LLVMFuzzerMutate(uint8_t* data, size_t size, size_t max_size);

// Half the mutations of an input holding a bag rewrite one of its chunks (fuzz/structure_mutators.h): lying
// declared sizes, zeros appended behind them, another codec. The rest, and any input without a chunk, libFuzzer's.
extern "C" size_t LLVMFuzzerCustomMutator(uint8_t* data, size_t size, size_t max_size, unsigned int seed) {
  driftlab::fuzz::Rng rng(seed);
  if (size >= 1 && max_size > 1 && data[0] < 64 && driftlab::fuzz::pick(rng, 2) == 0) {
    std::vector<uint8_t> out;
    if (driftlab::fuzz::mutate_bag(rng, {data + 1, size - 1}, max_size - 1, out)) {
      std::memcpy(data + 1, out.data(), out.size());
      return out.size() + 1;
    }
  }
  return LLVMFuzzerMutate(data, size, max_size);
}
