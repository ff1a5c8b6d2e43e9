// Every command on hostile logs: messages with valid framing whose payloads lie (negative and impossible lengths,
// cut short), and inputs that are not files. Nothing may crash, hang, or leave a partial file behind; the bad
// messages are counted and named, and every good one is still used.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/log_reader.h"
#include "core/log_writer.h"
#include "driftlab/imu_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "lcmtypes/stream_header.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

namespace fs = std::filesystem;
const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";
const std::string kSample = std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm";

test::CmdResult driftlab(const std::string& args) { return test::run_capture("timeout 60 " + kDriftlab + " " + args); }

using test::encode;
using test::put_be32;

/// The golden sample log with hostile messages among its own: a scan with -5 beams, an IMU whose frame name has
/// length -3, a TF message claiming 0x7fffffff transforms in 1.5 KB, and a ground-truth pose cut to 40 bytes.
/// Returns how many of each it wrote (one set every 50 events).
int write_hostile_log(const std::string& path) {
  int sets = 0;
  auto w = LogWriter::create(path);
  auto r = LogReader::open(kSample);
  if (!w.ok() || !r.ok()) return -1;
  Event e;
  int64_t n = 0, last = 0;
  while (r->next(e)) {
    if (!w->write(e.utime, e.channel, e.data).ok()) return -1;
    last = e.utime;
    if (++n % 50 != 0) continue;
    driftlab::laser_scan_t scan{};
    scan.header = {n, e.utime, "laser"};
    auto bad_scan = encode(scan);
    put_be32(bad_scan, lcmtypes::kHeaderFrameOffset + 4 + 6 + 7 * 4, -5);
    driftlab::imu_t imu{};
    imu.header = {n, e.utime, "imu"};
    auto bad_imu = encode(imu);
    put_be32(bad_imu, lcmtypes::kHeaderFrameOffset, -3);
    driftlab::tf_t tf{};
    tf.header = {n, e.utime, ""};
    auto bad_tf = encode(tf);
    put_be32(bad_tf, lcmtypes::kHeaderFrameOffset + 4 + 1, 0x7fffffff);
    bad_tf.resize(1500);
    driftlab::pose_t pose{};
    pose.header = {n, e.utime, "world"};
    auto cut = encode(pose);
    cut.resize(40);
    for (const auto& [channel, bytes] : {std::pair{"SCAN", &bad_scan}, {"IMU", &bad_imu}, {"TF", &bad_tf},
                                         {"GROUND_TRUTH", &cut}}) {
      if (!w->write(e.utime, channel, *bytes).ok()) return -1;
    }
    ++sets;
  }
  if (last == 0 || !w->close().ok()) return -1;
  return sets;
}

bool crashed(const test::CmdResult& r) {
  return r.code >= 124 || r.err.find("terminate") != std::string::npos ||
         r.err.find("runtime error") != std::string::npos;  // UBSan
}

void expect_no_partial_files(const std::string& dir) {
  for (const auto& f : fs::recursive_directory_iterator(dir)) {
    EXPECT_EQ(f.path().string().find(".partial"), std::string::npos) << f.path();
  }
}

TEST(HostileLog, EveryCommandCountsTheLiesAndUsesTheRest) {
  test::TempDir dir;
  const std::string log = dir.file("hostile.lcm");
  const int sets = write_hostile_log(log);
  ASSERT_GT(sets, 5);
  int64_t imu = 0;
  for (const auto& e : test::read_all(kSample)) imu += e.channel == "IMU";

  const auto d = driftlab("diagnose --json " + dir.file("d.json") + " " + log);
  ASSERT_FALSE(crashed(d)) << d.err;
  EXPECT_EQ(d.code, 0) << d.err;
  std::ifstream in(dir.file("d.json"));
  const auto j = nlohmann::json::parse(in);
  std::map<std::string, nlohmann::json> by_name;
  for (const auto& c : j["channels"]) by_name[c["name"]] = c;
  for (const char* channel : {"SCAN", "IMU", "TF", "GROUND_TRUTH"}) EXPECT_EQ(by_name[channel]["malformed"], sets);
  EXPECT_EQ(by_name["IMU"]["count"], imu);  // every good message still analysed
  EXPECT_EQ(by_name["GROUND_TRUTH"]["verdict"], "fault");
  EXPECT_NE(by_name["SCAN"]["reasons"].dump().find("ranges: length -5"), std::string::npos) << by_name["SCAN"];

  const auto rep = driftlab("report " + log + " -o " + dir.file("report"));
  EXPECT_FALSE(crashed(rep)) << rep.err;
  const auto replay = driftlab("replay " + log + " --modules slam,estimator --json -o " + dir.file("replay.lcm"));
  ASSERT_FALSE(crashed(replay)) << replay.err;
  ASSERT_EQ(replay.code, 0) << replay.err;
  const auto rj = nlohmann::json::parse(replay.out);
  for (const auto& m : rj["modules"]) {
    EXPECT_GT(m["dropped"].get<int64_t>(), 0) << m;
    EXPECT_NE(m["warnings"].dump().find("malformed"), std::string::npos) << m;
  }
  EXPECT_GE(rj["modules"][1]["outputs"].get<int64_t>(), 45);  // the estimator ran on the good ones (50 Hz, 1 s)

  const auto csv = driftlab("export csv " + log + " -o " + dir.file("csv"));
  EXPECT_FALSE(crashed(csv)) << csv.err;
  const auto rawlog = driftlab("export rawlog " + log + " -o " + dir.file("x.rawlog"));
  EXPECT_FALSE(crashed(rawlog)) << rawlog.err;
  const auto tum = driftlab("export tum " + log + ":GROUND_TRUTH -o " + dir.file("gt.tum"));
  EXPECT_FALSE(crashed(tum)) << tum.err;
  const auto eval = driftlab("eval --gt " + log + ":GROUND_TRUTH --est " + log + ":ODOM");
  EXPECT_FALSE(crashed(eval)) << eval.err;
  expect_no_partial_files(dir.path());
}

TEST(HostileLog, AFifoIsRefusedAtOnceNotWaitedOn) {
  // Opening a FIFO with no writer for reading blocks forever; every command must refuse it with one line instead.
  test::TempDir dir;
  const std::string fifo = dir.file("pipe.lcm");
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  for (const std::string& cmd : std::vector<std::string>{"info ", "diagnose ", "export csv -o " + dir.file("csv") + " "}) {
    const auto r = driftlab(cmd + fifo);
    EXPECT_EQ(r.code, 2) << cmd << r.err;
    EXPECT_NE(r.err.find("not a regular file"), std::string::npos) << cmd << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
}

TEST(NonsenseOptions, AreRefusedWithOneReadableLine) {
  // NaN, infinities, overflowing numbers and contradictions used to pass (sim --duration nan ran 600 s, the seed
  // was clamped, CLI11 printed the largest double in full).
  struct Case {
    std::string args, message;
  };
  const std::vector<Case> cases = {
      {"replay " + kSample + " --rate nan", "--rate: must be a finite number, got nan"},
      {"replay " + kSample + " --rate -1", "--rate: must be > 0, got -1"},
      {"replay " + kSample + " --start 5 --end 2", "--end 2 must be after --start 5"},
      {"replay " + kSample + " --start 1e308", "--start: is outside 0..1e+09 s, got 1e308"},
      {"replay " + kSample + " --start 900", "--start 900: nothing to replay after it"},
      {"replay " + kSample + " --start 1e309", "--start: must be a finite number, got 1e309"},
      {"sim --duration nan", "--duration: must be a finite number, got nan"},
      {"sim --seed 18446744073709551615", "--seed: is outside 0..9007199254740991, got 18446744073709551615"},
      {"diagnose --max-lag inf " + kSample, "--max-lag: must be a finite number, got inf"},
      {"record --flush-interval nan -o x.lcm", "--flush-interval: must be a finite number, got nan"},
      {"record --flush-interval -1 -o x.lcm", "--flush-interval: must be > 0, got -1"},
      // Finite but nonsense: each of these was accepted (a pace of 1e300 times real time, a 1e300 s simulation,
      // a log synced once in 3e292 years, 99999 processes, an offset no clock has).
      {"replay " + kSample + " --rate 1e300", "--rate: must be <= 1e+06, got 1e300"},
      {"sim --duration 1e300", "--duration: must be <= 1e+07 s, got 1e300"},
      {"record --flush-interval 1e300 -o x.lcm", "--flush-interval: must be <= 3600 s, got 1e300"},
      {"sweep --jobs 99999 spec.yaml", "--jobs: is outside 0..4096, got 99999"},
      {"eval --gt a.tum --est b.tum --offset 1e300", "--offset: is outside -1e+10..1e+10 s, got 1e300"},
      {"eval --gt a.tum --est b.tum --delta-tol 5", "--delta-tol: is outside 0..1, got 5"},
      {"demo --estimator-window 61", "--estimator-window: is outside 0..60 s, got 61"},
      {"export mcap " + kSample + " -o x.mcap --chunk-mb 0", "--chunk-mb: is outside 0.001..1024 MiB, got 0"},
      {"diagnose --max-lag 1e9 " + kSample, "--max-lag: must be <= 10 s, got 1e9"},
      {"replay " + kSample + " --reorder-window 1e9", "--reorder-window: is outside 0..3600 s, got 1e9"},
  };
  for (const auto& c : cases) {
    const auto r = driftlab(c.args);
    EXPECT_EQ(r.code, 2) << c.args << "\n" << r.err;
    EXPECT_EQ(r.err.rfind("driftlab: " + c.message, 0), 0u) << c.args << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_LT(r.err.size(), 200u) << r.err;
  }
}

TEST(OutputOverInput, IsRefusedBeforeAnythingIsWritten) {
  // The same file by another name (a hard link) is caught too: the check is by inode.
  test::TempDir dir;
  const std::string log = dir.file("x.lcm"), link = dir.file("y.lcm");
  fs::copy_file(kSample, log);
  fs::create_hard_link(log, link);
  const auto before = test::read_file(log);
  for (const std::string& cmd : std::vector<std::string>{
           "replay " + log + " -o " + link, "diagnose --json " + link + " " + log, "export tum " + log +
           ":GROUND_TRUTH -o " + link, "import rawlog " + log + " -o " + log, "export rawlog " + log + " -o " + log}) {
    const auto r = driftlab(cmd);
    EXPECT_EQ(r.code, 2) << cmd << "\n" << r.err;
    EXPECT_NE(r.err.find("is the input"), std::string::npos) << cmd << "\n" << r.err;
    EXPECT_EQ(test::read_file(log), before) << cmd;
  }
  expect_no_partial_files(dir.path());
}

}  // namespace
}  // namespace driftlab
