// Every command on hostile logs: messages with valid framing whose payloads lie (negative and impossible lengths,
// cut short), and inputs that are not files. Nothing may crash, hang, or leave a partial file behind; the bad
// messages are counted and named, and every good one is still used.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>

#include "core/log_reader.h"
#include "core/log_writer.h"
#include "driftlab/command_comparison_t.hpp"
#include "driftlab/imu_t.hpp"
#include "driftlab/laser_scan_t.hpp"
#include "driftlab/odometry_t.hpp"
#include "driftlab/pose_t.hpp"
#include "driftlab/tf_t.hpp"
#include "driftlab/velocity_command_t.hpp"
#include "lcmtypes/stream_header.h"
#include "lcmtypes/validate.h"
#include "tests/test_util.h"

namespace driftlab {
namespace {

namespace fs = std::filesystem;
const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";
const std::string kSample = std::string(DRIFTLAB_TEST_DATA) + "/sample.lcm";

test::CmdResult driftlab(const std::string& args) { return test::run_capture("timeout 60 " + kDriftlab + " " + args); }

using test::encode;
using test::put_be32;

/// The golden sample log with hostile messages among its own: a scan with -5 beams and one claiming 0x7fffffff
/// beams in 1.5 KB, an IMU whose frame name has length -3, a TF message claiming 0x7fffffff transforms in 1.5 KB,
/// and a ground-truth pose cut to 40 bytes. Returns how many sets it wrote (one set every 50 events).
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
    auto huge_scan = encode(scan);  // 0x7fffffff beams in 1.5 KB: memory grew by 330 MB/s (diagnose, export rawlog)
    put_be32(huge_scan, lcmtypes::kHeaderFrameOffset + 4 + 6 + 7 * 4, 0x7fffffff);
    huge_scan.resize(1500);
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
    for (const auto& [channel, bytes] : {std::pair{"SCAN", &bad_scan},
                                         {"SCAN", &huge_scan},
                                         {"IMU", &bad_imu},
                                         {"TF", &bad_tf},
                                         {"GROUND_TRUTH", &cut}}) {
      if (!w->write(e.utime, channel, *bytes).ok()) return -1;
    }
    ++sets;
  }
  if (last == 0 || !w->close().ok()) return -1;
  return sets;
}

/// Whether a message shows C++ or MRPT internals rather than saying what is wrong.
bool shows_internals(const std::string& err) {
  return err.find("==== MRPT") != std::string::npos || err.find("_M_") != std::string::npos ||
         err.find("std::") != std::string::npos || err.find("Call stack") != std::string::npos;
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

  const auto d = driftlab("diagnose --json-out " + dir.file("d.json") + " " + log);
  ASSERT_FALSE(crashed(d)) << d.err;
  EXPECT_EQ(d.code, 0) << d.err;
  std::ifstream in(dir.file("d.json"));
  const auto j = nlohmann::json::parse(in);
  std::map<std::string, nlohmann::json> by_name;
  for (const auto& c : j["channels"]) by_name[c["name"]] = c;
  for (const char* channel : {"IMU", "TF", "GROUND_TRUTH"}) EXPECT_EQ(by_name[channel]["malformed"], sets);
  EXPECT_EQ(by_name["SCAN"]["malformed"], 2 * sets);
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
  // The poses cut short were exported as broken rows: every row has the header's columns, one per intact pose.
  int64_t poses = 0;
  for (const auto& e : test::read_all(kSample)) poses += e.channel == "GROUND_TRUTH";
  std::ifstream gt(dir.file("csv/GROUND_TRUTH.csv"));
  std::string line;
  std::vector<size_t> columns;
  while (std::getline(gt, line)) columns.push_back(static_cast<size_t>(std::count(line.begin(), line.end(), ',')));
  ASSERT_EQ(columns.size(), static_cast<size_t>(poses) + 1);  // the header, then the intact poses only
  for (const size_t c : columns) EXPECT_EQ(c, columns[0]);
  EXPECT_NE(csv.out.find(std::to_string(sets) +
                         " malformed messages skipped (first: position.x: the message ends inside it)"),
            std::string::npos)
      << csv.out;
  const auto rawlog = driftlab("export rawlog " + log + " -o " + dir.file("x.rawlog"));
  EXPECT_FALSE(crashed(rawlog)) << rawlog.err;
  const auto tum = driftlab("export tum " + log + ":GROUND_TRUTH -o " + dir.file("gt.tum"));
  EXPECT_FALSE(crashed(tum)) << tum.err;
  const auto eval = driftlab("eval --gt " + log + ":GROUND_TRUTH --est " + log + ":ODOM");
  EXPECT_FALSE(crashed(eval)) << eval.err;
  for (const auto* r : {&d, &rep, &replay, &csv, &rawlog, &tum, &eval}) {  // vector::_M_default_append was printed
    EXPECT_FALSE(shows_internals(r->err)) << r->err;
  }
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

TEST(HostileConfig, AFifoForAYamlFileIsRefusedAtOnceNotWaitedOn) {
  // Every YAML file a command reads goes through core/text_file.h, which refuses what is not a regular file without
  // waiting for a writer: module settings, restamp files, fault descriptions, scenarios and sweep specs.
  test::TempDir dir;
  const std::string fifo = dir.file("pipe.yaml");
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  const std::string out = " -o " + dir.file("out");
  const std::vector<std::string> commands = {
      "replay " + kSample + " --modules estimator --config " + fifo + out,
      "replay " + kSample + " --restamp " + fifo + out,
      "replay " + kSample + " --inject " + fifo + out,
      "sim " + fifo + out,
      "sweep " + fifo + out,
  };
  for (const std::string& cmd : commands) {
    const auto r = driftlab(cmd);
    EXPECT_EQ(r.code, 2) << cmd << "\n" << r.err;
    EXPECT_EQ(r.err.rfind("driftlab: " + fifo + ": ", 0), 0u) << cmd << "\n" << r.err;
    EXPECT_NE(r.err.find("not a regular file"), std::string::npos) << cmd << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << cmd << "\n" << r.err;
    EXPECT_FALSE(fs::exists(dir.file("out"))) << cmd;
  }
  expect_no_partial_files(dir.path());
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
           "replay " + log + " -o " + link, "diagnose --json-out " + link + " " + log,
           "export tum " + log + ":GROUND_TRUTH -o " + link, "import rawlog " + log + " -o " + log,
           "export rawlog " + log + " -o " + log, "recover " + log + " -o " + link,
           "eval --gt " + log + ":GROUND_TRUTH --est " + log + ":GROUND_TRUTH --json-out " + link,
           "sim " + log + " -o " + link,  // a scenario by the name of its output (any content: refused first)
           // --json-out, in every command that has it
           "info " + log + " --json-out " + link, "recover " + log + " -o " + dir.file("r.lcm") + " --json-out " + link,
           "replay " + log + " --json-out " + link,
           "replay " + log + " --closed-loop -o " + dir.file("c.lcm") + " --json-out " + link,
           "sim " + log + " -o " + dir.file("s.lcm") + " --json-out " + link}) {
    const auto r = driftlab(cmd);
    EXPECT_EQ(r.code, 2) << cmd << "\n" << r.err;
    EXPECT_NE(r.err.find("is the input"), std::string::npos) << cmd << "\n" << r.err;
    EXPECT_EQ(test::read_file(log), before) << cmd;
  }
  // --json-out naming the command's own output: refused before either is written.
  for (const std::string& cmd : std::vector<std::string>{
           "replay " + log + " -o " + dir.file("o.lcm") + " --json-out " + dir.file("o.lcm"),
           "recover " + log + " -o " + dir.file("o.lcm") + " --json-out " + dir.file("o.lcm"),
           "diagnose " + log + " --html " + dir.file("o.lcm") + " --json-out " + dir.file("o.lcm")}) {
    const auto r = driftlab(cmd);
    EXPECT_EQ(r.code, 2) << cmd << "\n" << r.err;
    EXPECT_NE(r.err.find("is also where the command writes"), std::string::npos) << cmd << "\n" << r.err;
    EXPECT_FALSE(fs::exists(dir.file("o.lcm"))) << cmd;
  }
  // The simulator writes its fault manifest beside its log (o.faults.json beside o.lcm): neither --json-out nor the
  // scenario may be it.
  const std::string manifest = dir.file("o.faults.json");
  for (const std::string& cmd :
       std::vector<std::string>{"sim " + log + " -o " + dir.file("o.lcm") + " --json-out " + manifest,
                                "sim " + manifest + " -o " + dir.file("o.lcm")}) {
    if (cmd.find("sim " + manifest) == 0) test::write_file(manifest, {'x'});
    const auto r = driftlab(cmd);
    EXPECT_EQ(r.code, 2) << cmd << "\n" << r.err;
    EXPECT_TRUE(r.err.find("is also where the command writes") != std::string::npos ||
                r.err.find("is the input") != std::string::npos)
        << cmd << "\n"
        << r.err;
    EXPECT_FALSE(fs::exists(dir.file("o.lcm"))) << cmd;
  }
  EXPECT_EQ(test::read_file(manifest), std::vector<uint8_t>{'x'});  // the scenario by the manifest's name, kept
  expect_no_partial_files(dir.path());
}

/// Every file under dir (folders left out) with its bytes.
std::map<std::string, std::vector<uint8_t>> files_in(const std::string& dir) {
  std::map<std::string, std::vector<uint8_t>> m;
  for (const auto& f : fs::recursive_directory_iterator(dir)) {
    if (f.is_regular_file()) m[f.path().string()] = test::read_file(f.path().string());
  }
  return m;
}

TEST(OutputOverInput, AFileInsideAnInputBagFolderIsRefused) {
  // The check compared -o with the bag folder only, so `import BAG -o BAG/x_0.mcap` replaced the bag's own storage
  // file (and diagnose --json-out, export tum and eval --json-out into the folder did the same). Now an output that is,
  // or lies inside, an input folder is refused before anything is read, by its path with links resolved.
  test::TempDir dir;
  const std::string bag = dir.file("bag");
  ASSERT_EQ(driftlab("export rosbag2 " + kSample + " -o " + bag).code, 0);
  std::string storage;
  for (const auto& f : fs::directory_iterator(bag)) {
    if (f.path().extension() == ".mcap") storage = f.path().string();
  }
  ASSERT_FALSE(storage.empty());
  const std::string metadata = bag + "/metadata.yaml";
  fs::create_symlink(storage, dir.file("link.mcap"));  // outside the folder by name, inside it by where it leads
  const auto before = files_in(bag);
  for (const std::string& cmd : std::vector<std::string>{
           "import " + bag + " -o " + storage, "import " + bag + " -o " + bag + "/new.lcm",
           "import " + bag + "/ -o " + metadata, "import " + bag + " -o " + dir.file("link.mcap"),
           "diagnose --json-out " + metadata + " " + bag, "diagnose --html " + storage + " " + bag,
           "export tum " + bag + ":GROUND_TRUTH -o " + storage, "export csv " + bag + " -o " + bag + "/csv",
           "export mcap " + bag + " -o " + storage,
           "eval --gt " + bag + ":GROUND_TRUTH --est " + kSample + ":GROUND_TRUTH --json-out " + metadata,
           "replay " + bag + " -o " + storage}) {
    const auto r = driftlab(cmd);
    EXPECT_EQ(r.code, 2) << cmd << "\n" << r.err;
    EXPECT_NE(r.err.find("is inside the input folder " + bag), std::string::npos) << cmd << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << cmd << "\n" << r.err;
    EXPECT_EQ(files_in(bag), before) << cmd;  // nothing written into the bag, nothing of it replaced
  }
  EXPECT_TRUE(fs::is_symlink(dir.file("link.mcap")));
  // Beside the folder is fine.
  EXPECT_EQ(driftlab("import " + bag + " -o " + dir.file("beside.lcm")).code, 0);
  expect_no_partial_files(dir.path());
}

TEST(OutputOverInput, AnOutputThatIsNotARegularFileIsRefusedAndKept) {
  // Outputs are written beside their path and renamed into place, so -o naming a FIFO or a character device
  // replaced the node with a regular file (as root, `-o /dev/null` replaced /dev/null itself). Refused, one line,
  // exit 2, the node left as it was. (/dev/null itself is not used here: a copy of it is made when the test can.)
  test::TempDir dir;
  const std::string fifo = dir.file("fifo"), null = dir.file("null");
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  std::vector<std::pair<std::string, std::string>> nodes = {{fifo, "a FIFO"}};
  if (::mknod(null.c_str(), S_IFCHR | 0666, makedev(1, 3)) == 0) nodes.emplace_back(null, "a character device");
  fs::create_directories(dir.file("folder"));
  nodes.emplace_back(dir.file("folder"), "a folder");
  for (const auto& [node, kind] : nodes) {
    for (const std::string& cmd : std::vector<std::string>{
             "replay " + kSample + " -o " + node, "diagnose --json-out " + node + " " + kSample,
             "export tum " + kSample + ":GROUND_TRUTH -o " + node, "recover " + kSample + " -o " + node,
             "eval --gt " + kSample + ":GROUND_TRUTH --est " + kSample + ":GROUND_TRUTH --json-out " + node,
             "export mcap " + kSample + " -o " + node, "export rawlog " + kSample + " -o " + node}) {
      const auto r = driftlab(cmd);
      EXPECT_EQ(r.code, 2) << cmd << "\n" << r.err;
      EXPECT_NE(r.err.find(node + ": is " + kind + ", not a regular file"), std::string::npos) << cmd << "\n" << r.err;
      EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << cmd << "\n" << r.err;
      struct stat st {};
      ASSERT_EQ(::lstat(node.c_str(), &st), 0) << cmd;
      EXPECT_FALSE(S_ISREG(st.st_mode)) << cmd << ": " << node << " was replaced";
    }
  }
  // A folder output (export csv, export rosbag2, report) refuses a FIFO the same way.
  const auto r = driftlab("export csv " + kSample + " -o " + fifo);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find(fifo + ": is a FIFO, not a folder"), std::string::npos) << r.err;
  expect_no_partial_files(dir.path());
}

/// A recording another tool made (an MCAP file of the sample) and the path of its cached conversion.
std::pair<std::string, std::string> mcap_recording(const test::TempDir& dir) {
  const std::string mcap = dir.file("rec.mcap");
  EXPECT_EQ(driftlab("export mcap " + kSample + " -o " + mcap).code, 0);
  return {mcap, mcap + ".dlimport.lcm"};
}

/// A small LCM log that is not the recording's conversion: one event on EVIL.
std::string other_log(const test::TempDir& dir) {
  std::string path = dir.file("other.lcm");
  auto w = LogWriter::create(path);
  EXPECT_TRUE(w.ok());
  EXPECT_TRUE(w->write(1000, "EVIL", std::string_view("not the recording")).ok());
  EXPECT_TRUE(w->close().ok());
  return path;
}

TEST(ConversionCache, ARecordingEditedInPlaceWithItsTimesRestoredIsConvertedAgain) {
  test::TempDir dir;
  const auto [mcap, cache] = mcap_recording(dir);
  auto r = driftlab("info " + mcap);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("converting it to " + cache), std::string::npos) << r.err;
  r = driftlab("info " + mcap);
  EXPECT_NE(r.err.find("reading its conversion " + cache), std::string::npos) << r.err;
  // One byte changed in the middle, size kept, modification time put back as it was.
  struct stat st {};
  ASSERT_EQ(::stat(mcap.c_str(), &st), 0);
  auto bytes = test::read_file(mcap);
  bytes[bytes.size() / 2] ^= 0x5a;
  test::write_file(mcap, bytes);
  const struct timespec times[2] = {st.st_atim, st.st_mtim};
  ASSERT_EQ(::utimensat(AT_FDCWD, mcap.c_str(), times, 0), 0);
  r = driftlab("info " + mcap);
  EXPECT_NE(r.err.find("converting it to " + cache), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("reading its conversion"), std::string::npos) << r.err;
}

TEST(ConversionCache, ALinkOrAnOutputInPlaceOfTheConversionIsNotBelieved) {
  test::TempDir dir;
  const auto [mcap, cache] = mcap_recording(dir);
  const std::string other = other_log(dir);
  auto r = driftlab("info " + mcap);
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string healthy = r.out;
  ASSERT_EQ(healthy.find("EVIL"), std::string::npos);
  // The conversion replaced by a symbolic link to another log.
  fs::remove(cache);
  fs::create_symlink(other, cache);
  r = driftlab("info " + mcap);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find(cache + " is a symbolic link; converting it again"), std::string::npos) << r.err;
  EXPECT_EQ(r.out, healthy);
  EXPECT_FALSE(fs::is_symlink(cache));
  EXPECT_EQ(test::read_all(other).size(), 1u);  // the link's target left alone
  // An output written over the conversion (any command's -o): remade, not read.
  r = driftlab("recover " + other + " -o " + cache);
  ASSERT_EQ(r.code, 0) << r.err;
  r = driftlab("info " + mcap);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find(cache + " is not the file made then"), std::string::npos) << r.err;
  EXPECT_EQ(r.out, healthy);
  r = driftlab("info " + mcap);  // and the remade one is believed again
  EXPECT_NE(r.err.find("reading its conversion " + cache), std::string::npos) << r.err;
  // A key (CACHE.key) that is a link is not read either.
  fs::remove(cache + ".key");
  fs::create_symlink(other, cache + ".key");
  r = driftlab("info " + mcap);
  EXPECT_NE(r.err.find("converting it to " + cache), std::string::npos) << r.err;
  EXPECT_EQ(r.out, healthy);
}

TEST(ConversionCache, TwoProcessesConvertingOneRecordingEachWriteTheirOwnPartialFile) {
  // They shared CACHE.partial: one renamed the other's half-written file into place (garbage, exit 0) and the
  // other failed. Each now writes a partial file of its own, created exclusively; the last whole one wins.
  test::TempDir dir;
  const auto [mcap, cache] = mcap_recording(dir);
  const auto healthy = driftlab("info " + mcap);
  ASSERT_EQ(healthy.code, 0) << healthy.err;
  for (int round = 0; round < 3; ++round) {
    fs::remove(cache);
    fs::remove(cache + ".key");
    const std::string cmd = "timeout 60 " + kDriftlab + " info " + mcap;
    const auto r =
        test::run_capture("(" + cmd + " > " + dir.file("a.out") + " 2>&1; echo $? > " + dir.file("a.rc") + ") & (" +
                          cmd + " > " + dir.file("b.out") + " 2>&1; echo $? > " + dir.file("b.rc") + ") & wait");
    ASSERT_EQ(r.code, 0);
    for (const char* who : {"a", "b"}) {
      const auto rc = test::read_file(dir.file(std::string(who) + ".rc"));
      EXPECT_EQ(std::string(rc.begin(), rc.end()), "0\n") << who;
    }
    expect_no_partial_files(dir.path());
    // The conversion in place is whole (should the key name the file the other process replaced, it is made once
    // more: never read wrong).
    const auto after = driftlab("info " + mcap);
    EXPECT_EQ(after.code, 0) << after.err;
    EXPECT_EQ(after.out, healthy.out);
  }
}

// A recording whose name is long (here 240 bytes, which the file system holds) was refused: its cache's files,
// NAME.dlimport.lcm.key.partial.PID.N, are over 255 bytes ("File name too long"). The cache's name is cut and
// hashed; two long names alike in their first 100 bytes get caches of their own.
TEST(ConversionCache, ARecordingWithALongNameIsConverted) {
  test::TempDir dir;
  const auto [mcap, unused] = mcap_recording(dir);
  const auto healthy = driftlab("info " + mcap);
  ASSERT_EQ(healthy.code, 0) << healthy.err;
  for (const char last : {'a', 'b'}) {
    const std::string name = dir.file(std::string(235, 'x') + last + ".mcap");
    fs::copy_file(mcap, name);
    auto r = driftlab("info " + name);
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(r.out.substr(r.out.find('\n')), healthy.out.substr(healthy.out.find('\n')));
    EXPECT_NE(r.err.find("converting it to " + dir.file(std::string(100, 'x') + "~")), std::string::npos) << r.err;
    r = driftlab("info " + name);
    EXPECT_NE(r.err.find("reading its conversion"), std::string::npos) << r.err;
  }
  expect_no_partial_files(dir.path());
}

/// Every command that reads a log, with OUT as the output of those that write one.
std::vector<std::string> log_readers(const std::string& log, const test::TempDir& dir) {
  return {"info " + log,
          "diagnose " + log,
          "diagnose --json-out " + dir.file("d.json") + " " + log,
          "replay " + log + " -o " + dir.file("r.lcm"),
          "export csv " + log + " -o " + dir.file("csv"),
          "export tum " + log + ":GROUND_TRUTH -o " + dir.file("t.tum"),
          "export rawlog " + log + " -o " + dir.file("x.rawlog"),
          "report " + log + " -o " + dir.file("report"),
          "eval --gt " + log + ":GROUND_TRUTH --est " + kSample + ":GROUND_TRUTH",
          "recover " + log + " -o " + dir.file("c.lcm")};
}

TEST(NotALog, EveryCommandThatReadsLogsSaysSoAndExits2) {
  // Random bytes, zeros and an empty file used to be "no timing problems found" (diagnose) and exit 0 (replay,
  // export rawlog, with an empty output written). 64 MB of zeros here (a sparse file; 4 GB takes 2 s, checked by
  // hand). A FIFO is refused at once by every command.
  test::TempDir dir;
  std::vector<uint8_t> random(100000);
  uint64_t x = 88172645463325252ull;
  for (auto& b : random) b = static_cast<uint8_t>((x ^= x << 13, x ^= x >> 7, x ^= x << 17) >> 56);
  test::write_file(dir.file("random.lcm"), random);
  test::write_file(dir.file("zeros.lcm"), {});
  ASSERT_EQ(::truncate(dir.file("zeros.lcm").c_str(), 64 << 20), 0);
  test::write_file(dir.file("empty.lcm"), {});
  ASSERT_EQ(mkfifo(dir.file("fifo.lcm").c_str(), 0600), 0);  // opening it to read would block without a writer
  for (const auto& [name, message] : {std::pair{"random.lcm", "not an LCM event log (no event in 100000 bytes"},
                                      {"zeros.lcm", "not an LCM event log (no event in 67108864 bytes"},
                                      {"empty.lcm", "empty file (0 bytes): no events"},
                                      {"fifo.lcm", "not a regular file (a FIFO, device or socket)"}}) {
    const std::string log = dir.file(name);
    for (const auto& cmd : log_readers(log, dir)) {
      if (cmd.rfind("info", 0) == 0 && std::string(name) == "empty.lcm") continue;  // info describes it (below)
      const auto r = driftlab(cmd);
      EXPECT_EQ(r.code, 2) << cmd << "\n" << r.err;
      EXPECT_NE(r.err.find(log + ": " + message), std::string::npos) << cmd << "\n" << r.err;
      EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << cmd << "\n" << r.err;
      EXPECT_EQ(r.out.find("no timing problems"), std::string::npos) << cmd;
      EXPECT_FALSE(shows_internals(r.err)) << cmd << "\n" << r.err;
    }
    for (const char* out : {"d.json", "r.lcm", "csv", "t.tum", "x.rawlog", "report", "c.lcm"}) {
      EXPECT_FALSE(fs::exists(dir.file(out))) << name << " left " << out;
    }
  }
  // An empty file is a log of no events (what lcm-logger leaves when nothing came): info says so, with exit 0.
  const auto info = driftlab("info " + dir.file("empty.lcm"));
  EXPECT_EQ(info.code, 0) << info.err;
  EXPECT_NE(info.out.find("the file is empty"), std::string::npos) << info.out;
  expect_no_partial_files(dir.path());
}

TEST(NotALog, ALogDamagedThroughoutIsNamedAsSuch) {
  // It starts like a log, but no event is whole: not "not a log", and still nothing to work on.
  test::TempDir dir;
  auto bytes = test::read_file(kSample);
  bytes.resize(20);
  test::write_file(dir.file("cut.lcm"), bytes);
  const auto r = driftlab("diagnose " + dir.file("cut.lcm"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("cut.lcm: no intact event in 20 bytes"), std::string::npos) << r.err;
}

/// The log `from` (the sample log) with the first and every `every`-th message after it on `channel` rewritten by
/// `edit` (which gets the decoded message and its index on the channel) into `path`; returns how many were
/// rewritten.
template <typename T, typename F>
int rewrite_sample(const std::string& path, const std::string& channel, int every, F edit,
                   const std::string& from = kSample) {
  const auto events = test::read_all(from);  // before writing: path may be from
  auto w = LogWriter::create(path);
  if (!w.ok()) return -1;
  int n = 0, rewritten = 0;
  for (const auto& e : events) {
    std::vector<uint8_t> data = e.data;
    if (e.channel == channel && n++ % every == 0) {
      T m;
      if (m.decode(data.data(), 0, static_cast<int>(data.size())) < 0) return -1;
      edit(m, n - 1);
      data = encode(m);
      ++rewritten;
    }
    if (!w->write(e.utime, e.channel, data).ok()) return -1;
  }
  return w->close().ok() ? rewritten : -1;
}

/// Every message on `channel` of a log, as T.
template <typename T>
std::vector<T> messages(const std::string& path, const std::string& channel) {
  std::vector<T> out;
  for (const auto& e : test::read_all(path)) {
    if (e.channel != channel) continue;
    EXPECT_EQ(lcmtypes::non_finite(e.data), std::nullopt) << channel << " at " << e.utime;
    T m;
    if (m.decode(e.data.data(), 0, static_cast<int>(e.data.size())) >= 0) out.push_back(m);
  }
  return out;
}

nlohmann::json module_report(const nlohmann::json& replay, const std::string& name) {
  for (const auto& m : replay["modules"]) {
    if (m["name"] == name) return m;
  }
  return {};
}

TEST(HostileValues, NanTwistsNeverReachTheEstimate) {
  // NaN in 5% of the odometry twists made nearly every EKF output NaN for the rest of the run, without a warning.
  test::TempDir dir;
  const std::string log = dir.file("nan.lcm");
  const int nan = rewrite_sample<driftlab::odometry_t>(log, "ODOM", 20,
                                                       [](driftlab::odometry_t& o, int) { o.linear_velocity.x = NAN; });
  ASSERT_GT(nan, 1);
  const auto r = driftlab("replay " + log + " --modules estimator,controller --json -o " + dir.file("out.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const auto est = module_report(j, "estimator");
  EXPECT_EQ(est["dropped"].get<int64_t>(), nan) << est;
  EXPECT_EQ(est["metrics"]["non_finite_dropped"].get<double>(), nan) << est;
  EXPECT_NE(est["warnings"].dump().find("estimator: " + std::to_string(nan) +
                                        " inputs with NaN, infinite or out-of-range numbers dropped (first: ODOM: "
                                        "linear_velocity.x = nan)"),
            std::string::npos)
      << est;
  const auto estimates = messages<driftlab::odometry_t>(dir.file("out.lcm"), "EKF_ODOM");  // all finite
  EXPECT_GE(estimates.size(), 45u);  // 50 Hz over the sample's second
  // The controller follows the odometry's pose: a message with a NaN in it is dropped there too.
  EXPECT_EQ(module_report(j, "controller")["dropped"].get<int64_t>(), nan);
  (void)messages<driftlab::velocity_command_t>(dir.file("out.lcm"), "CMD_REPLAY");
}

TEST(HostileValues, SlamSkipsAScanWithANanAngleIncrementAndSaysSo) {
  // MRPT's occupancy grid asserted on such a scan (the first, a keyframe): `replay --modules slam` aborted,
  // leaving OUT.partial behind.
  test::TempDir dir;
  const std::string log = dir.file("nan.lcm");
  const int nan = rewrite_sample<driftlab::laser_scan_t>(
      log, "SCAN", 3, [](driftlab::laser_scan_t& s, int) { s.angle_increment = NAN; });
  ASSERT_GE(nan, 3);
  const auto r = driftlab("replay " + log + " --modules slam --json -o " + dir.file("out.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto slam = module_report(nlohmann::json::parse(r.out), "slam");
  EXPECT_EQ(slam["dropped"].get<int64_t>(), nan) << slam;
  EXPECT_NE(slam["warnings"].dump().find("(first: SCAN: angle_increment = nan)"), std::string::npos) << slam;
  EXPECT_EQ(slam["warnings"].dump().find("failed on"), std::string::npos) << slam;  // skipped, not thrown
  EXPECT_FALSE(messages<driftlab::pose_t>(dir.file("out.lcm"), "SLAM_POSE").empty());
}

TEST(HostileValues, HugeNumbersAndStampsAreRefusedNotOverflowed) {
  // What the module fuzzer found: a scanner placed 1e15 m from the base made MRPT's grid ask for more cells than
  // memory holds (a segfault in resizeGrid); a stamp at the end of int64_t overflowed the estimator's publication
  // schedule (and stepping to it took 4e14 steps: replay hung); logged commands of 1e300 made the controller's
  // comparison infinite. At the finest map_resolution the config takes (1 mm), a map of 30 m is 9e8 cells (1 GB
  // in MRPT's grid, as much again in the image): left undrawn, with a warning.
  test::TempDir dir;
  const std::string log = dir.file("huge.lcm");
  ASSERT_GT(rewrite_sample<driftlab::tf_t>(log, "TF_STATIC", 1,
                                           [](driftlab::tf_t& tf, int) {
                                             for (auto& t : tf.transforms) t.translation.x = 1e15;
                                           }),
            0);
  ASSERT_GT(rewrite_sample<driftlab::odometry_t>(
                log, "ODOM", 50,
                [](driftlab::odometry_t& o, int n) {
                  if (n == 50) o.header.utime = std::numeric_limits<int64_t>::max();  // the last
                },
                log),
            0);
  const int huge = rewrite_sample<driftlab::velocity_command_t>(
      log, "CMD_VEL", 4, [](driftlab::velocity_command_t& c, int) { c.linear.x = 1e300; }, log);
  ASSERT_GT(huge, 1);
  const std::string config = dir.file("c.yaml");
  std::ofstream(config) << "controller:\n  logged_channel: CMD_VEL\nslam:\n  2d:\n    map_resolution: 0.001\n";
  const auto r = driftlab("replay " + log + " --modules slam,estimator,controller --config " + config + " --json -o " +
                          dir.file("out.lcm"));
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const auto slam = module_report(j, "slam"), ctl = module_report(j, "controller");
  EXPECT_NE(slam["warnings"].dump().find("(first: TF_STATIC: translation.x = 1e+15, beyond 1e+09)"), std::string::npos)
      << slam;
  EXPECT_NE(slam["warnings"].dump().find("not drawn (a coarser map_resolution draws it)"), std::string::npos) << slam;
  EXPECT_EQ(ctl["dropped"].get<int64_t>(), huge) << ctl;
  EXPECT_NE(ctl["warnings"].dump().find("(first: CMD_VEL: linear.x = 1e+300, beyond 1e+09)"), std::string::npos) << ctl;
  for (const auto& e : test::read_all(dir.file("out.lcm"))) {
    EXPECT_EQ(lcmtypes::non_finite(e.data), std::nullopt) << e.channel;
  }
  EXPECT_EQ(messages<driftlab::command_comparison_t>(dir.file("out.lcm"), "CMD_COMPARISON").size(), 1u);
}

/// Every file under dir that is empty or a temporary (.partial) one: what a failed command must not leave.
std::vector<std::string> left_behind(const std::string& dir) {
  std::vector<std::string> out;
  for (const auto& f : fs::recursive_directory_iterator(dir)) {
    const std::string path = f.path().string();
    if (path.find(".partial") != std::string::npos || (f.is_regular_file() && f.file_size() == 0)) out.push_back(path);
  }
  return out;
}

/// Every command that writes a file, each writing into out: the command line, and the file it writes ("": a folder).
/// in holds the rawlog and MCAP files it imports (made once by the caller).
std::vector<std::pair<std::string, std::string>> writing_commands(const std::string& in, const std::string& out) {
  const std::string rawlog = in + "/s.rawlog", mcap = in + "/s.mcap";
  return {
      {"diagnose --json-out " + out + "/d.json " + kSample, "d.json"},
      {"diagnose --html " + out + "/d.html " + kSample, "d.html"},
      {"export csv " + kSample + " -o " + out + "/csv", ""},
      {"export tum " + kSample + ":GROUND_TRUTH -o " + out + "/t.tum", "t.tum"},
      {"export rawlog " + kSample + " -o " + out + "/x.rawlog", "x.rawlog"},
      {"export mcap " + kSample + " -o " + out + "/x.mcap", "x.mcap"},
      {"export rosbag2 " + kSample + " -o " + out + "/bag", ""},
      {"replay " + kSample + " -o " + out + "/r.lcm", "r.lcm"},
      {"replay " + kSample + " --modules estimator -o " + out + "/m.lcm", "m.lcm"},
      {"recover " + kSample + " -o " + out + "/c.lcm", "c.lcm"},
      {"sim --duration 1 -o " + out + "/s.lcm", "s.lcm"},
      {"import rawlog " + rawlog + " -o " + out + "/i.lcm", "i.lcm"},
      {"import " + mcap + " -o " + out + "/j.lcm", "j.lcm"},
      {"eval --gt " + kSample + ":GROUND_TRUTH --est " + kSample + ":ODOM --json-out " + out + "/e.json", "e.json"},
      {"report " + kSample + " -o " + out + "/report", ""},
  };
}

/// Makes in/ with the files writing_commands imports.
void make_imported_inputs(const std::string& in) {
  fs::create_directories(in);
  ASSERT_EQ(driftlab("export rawlog " + kSample + " -o " + in + "/s.rawlog").code, 0);
  ASSERT_EQ(driftlab("export mcap " + kSample + " -o " + in + "/s.mcap").code, 0);
}

TEST(FullDisk, EveryCommandFailsWithCode1AndLeavesNothingBehind) {
  // A file-size limit of 1 KiB (ulimit -f 1) stands for a full disk: the write fails with EFBIG. SIGXFSZ used to
  // kill export csv and export rawlog halfway, leaving their partial files; sim and replay moved the log cut short
  // over an existing file of the same name. Every command that writes a file, each over a file the user already
  // has where it writes one: that file keeps what it held, and nothing empty or partial is left.
  test::TempDir dir;
  const std::string in = dir.file("in"), out = dir.file("out");
  fs::create_directories(out);
  make_imported_inputs(in);
  const std::string precious = "the user's own file\n";
  for (const auto& [cmd, file] : writing_commands(in, out)) {
    if (!file.empty()) std::ofstream(out + "/" + file) << precious;
    const auto r = test::run_capture("ulimit -f 1; timeout 60 " + kDriftlab + " " + cmd);
    EXPECT_EQ(r.code, 1) << cmd << "\n" << r.err;
    EXPECT_FALSE(shows_internals(r.err)) << cmd << "\n" << r.err;  // export rawlog said "==== MRPT exception ===="
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << cmd << "\n" << r.err;
    if (!file.empty()) {
      const auto kept = test::read_file(out + "/" + file);
      EXPECT_EQ(std::string(kept.begin(), kept.end()), precious) << cmd;
    }
    EXPECT_EQ(left_behind(dir.path()), std::vector<std::string>{}) << cmd;
  }
}

TEST(UnwritableOutput, EveryCommandFailsWithCode1NamingTheOutput) {
  // An output whose folder is a file (ENOTDIR) or a folder without write permission (EACCES; root may write anyway,
  // so that half is checked only when the folder refuses a file): the environment's fault, exit 1 (a bad input is
  // 2). The code comes from the error itself (ErrorCode::kCannotWrite) at every writer; exit_code_for once told
  // them apart by whether the message began with the output's path.
  test::TempDir dir;
  const std::string in = dir.file("in"), file = dir.file("a-file"), locked = dir.file("locked");
  make_imported_inputs(in);
  std::ofstream(file) << "not a folder\n";
  fs::create_directories(locked);
  fs::permissions(locked, fs::perms::owner_read | fs::perms::owner_exec);
  const bool locked_refuses = !std::ofstream(locked + "/probe");
  fs::remove(locked + "/probe");
  for (const std::string& out : {file, locked}) {
    if (out == locked && !locked_refuses) continue;
    for (const auto& [cmd, written] : writing_commands(in, out)) {
      const auto r = driftlab(cmd);
      EXPECT_EQ(r.code, 1) << cmd << "\n" << r.err;
      EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << cmd << "\n" << r.err;
      EXPECT_NE(r.err.find(out + "/"), std::string::npos) << cmd << "\n" << r.err;
      EXPECT_FALSE(shows_internals(r.err)) << cmd << "\n" << r.err;
    }
  }
  fs::permissions(locked, fs::perms::owner_all);
  EXPECT_EQ(left_behind(dir.path()), std::vector<std::string>{});
}

// A bag folder given that already holds files: the user's to clear or rename (exit 2, not 1: nothing failed to be
// written), in one line naming it, and what it holds is left as it was.
TEST(UnwritableOutput, ABagFolderThatIsNotEmptyIsTheUsersToClear) {
  test::TempDir dir;
  const std::string bag = dir.file("bag");
  fs::create_directories(bag);
  std::ofstream(bag + "/notes.txt") << "mine\n";
  const auto r = driftlab("export rosbag2 " + kSample + " -o " + bag);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_EQ(r.err,
            "driftlab: " + bag + ": exists and is not an empty folder (rosbag2 writes a bag into a new folder)\n");
  const auto kept = test::read_file(bag + "/notes.txt");
  EXPECT_EQ(std::string(kept.begin(), kept.end()), "mine\n");
  EXPECT_EQ(left_behind(dir.path()), std::vector<std::string>{});
}

// A disk that fills while report's Python draws (report.json written, the page not): a 51-line Python traceback and
// exit 2. Now one line naming the folder, exit 1, and the user's earlier page and plots kept whole.
TEST(FullDisk, ReportWhilePlottingIsOneLineAndCode1) {
  test::TempDir dir;
  const std::string out = dir.file("report");
  ASSERT_EQ(driftlab("report " + kSample + " -o " + out).code, 0);
  const auto page = test::read_file(out + "/index.html");
  ASSERT_GT(page.size(), 200u * 1024);
  // ulimit -f 200 (100 KiB in dash's 512-byte blocks, 200 in bash's): report.json (18 KiB) and each plot (under
  // 64 KiB) fit; the page (250 KiB) does not.
  const auto r = test::run_capture("ulimit -f 200; timeout 120 " + kDriftlab + " report " + kSample + " -o " + out);
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_EQ(r.err, "driftlab: " + out + ": cannot write the page: File too large\n");
  EXPECT_EQ(test::read_file(out + "/index.html"), page);  // the page the user had
  EXPECT_EQ(left_behind(dir.path()), std::vector<std::string>{});
}

// A disk that fills while a recording is converted for a command: exit 2 (bad input) naming the partial file, gone
// by then. Now exit 1 naming the recording and its conversion, and nothing left; the next run converts it whole.
TEST(FullDisk, ConvertingARecordingIsCode1NamingIt) {
  const std::string mcap = test::shared_data("bags/nav2_turtlebot.mcap");
  if (mcap.empty()) GTEST_SKIP() << "no shared data";
  test::TempDir dir;
  const std::string bag = dir.file("nav2.mcap");
  fs::copy_file(mcap, bag);
  for (const std::string& cmd : std::vector<std::string>{"info", "diagnose", "export csv -o " + dir.file("csv")}) {
    const auto r = test::run_capture("ulimit -f 1; timeout 60 " + kDriftlab + " " + cmd + " " + bag);
    EXPECT_EQ(r.code, 1) << cmd << "\n" << r.err;
    EXPECT_NE(r.err.find("driftlab: " + bag + ": cannot write its conversion " + bag +
                         ".dlimport.lcm: write failed at byte "),
              std::string::npos)
        << cmd << "\n"
        << r.err;
    EXPECT_TRUE(r.err.ends_with(": File too large\n")) << cmd << "\n" << r.err;
    EXPECT_EQ(r.err.find(".partial"), std::string::npos) << cmd << "\n" << r.err;
    EXPECT_EQ(left_behind(dir.path()), std::vector<std::string>{}) << cmd;
  }
  EXPECT_EQ(driftlab("info " + bag).code, 0);
}

TEST(BadInput, RecordAndDemoExitWith2) {
  // They exited 1 (an environment failure) for options the user got wrong.
  test::TempDir dir;
  for (const auto& [args, message] : std::vector<std::pair<std::string, std::string>>{
           {"record -c '[bad' -o " + dir.file("x.lcm"), "-c/--channels: invalid channel regex '[bad': "},
           {"record --exclude '(' -o " + dir.file("x.lcm"), "--exclude: invalid channel regex '(': "},
           {"record --url bogus:// -o " + dir.file("x.lcm"), "LCM URL 'bogus://': only udpm:// is supported"},
           {"demo /nonexistent.yaml -o " + dir.file("demo"), "demo: driftlab sim /nonexistent.yaml"}}) {
    const auto r = driftlab(args);
    EXPECT_EQ(r.code, 2) << args << "\n" << r.err;
    EXPECT_EQ(r.err.rfind("driftlab: " + message, 0), 0u) << args << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  EXPECT_FALSE(fs::exists(dir.file("x.lcm")));
  EXPECT_FALSE(fs::exists(dir.file("demo/sim.json")));  // the failed stage's (empty) output is not kept
}

TEST(BadInput, InjectAndRestampOnAChannelTheLogLacksAreRefused) {
  // They changed nothing and the replay reported success, as if the faults or corrections had been applied.
  test::TempDir dir;
  std::ofstream(dir.file("inject.yaml")) << "seed: 1\nstreams:\n  ODMO: {drop_probability: 0.5}\n";
  std::ofstream(dir.file("restamp.yaml")) << "channels:\n  IMU_RAW: {offset_s: 0.01}\n";
  for (const auto& [args, message] : std::vector<std::pair<std::string, std::string>>{
           {"--inject " + dir.file("inject.yaml"),
            "--inject " + dir.file("inject.yaml") + ": no channel 'ODMO' in the logs given (they have: "},
           {"--restamp " + dir.file("restamp.yaml"),
            "--restamp " + dir.file("restamp.yaml") + ": no channel 'IMU_RAW' in the logs given (they have: "}}) {
    const auto r = driftlab("replay " + kSample + " " + args + " -o " + dir.file("r.lcm"));
    EXPECT_EQ(r.code, 2) << args << "\n" << r.err;
    EXPECT_EQ(r.err.rfind("driftlab: " + message, 0), 0u) << r.err;
    EXPECT_NE(r.err.find("GROUND_TRUTH"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("r.lcm")));
  }
  // Contradictory flags pass with a warning: --fast replays as fast as it can, whatever --rate says.
  const auto fast = driftlab("replay " + kSample + " --fast --rate 5 -o " + dir.file("f.lcm"));
  EXPECT_EQ(fast.code, 0) << fast.err;
  EXPECT_EQ(fast.err, "driftlab: warning: --fast ignores --rate\n");
  // The channels the log has are taken as before.
  std::ofstream(dir.file("inject.yaml")) << "seed: 1\nstreams:\n  ODOM: {drop_probability: 0.5}\n";
  EXPECT_EQ(driftlab("replay " + kSample + " --inject " + dir.file("inject.yaml") + " -o " + dir.file("r.lcm")).code,
            0);
}

TEST(BadInput, EvalNamesALogGivenWithoutItsChannel) {
  // It was read as a TUM file: "sample.lcm:1: not a number".
  for (const std::string& args : {"--gt " + kSample + " --est " + kSample + ":GROUND_TRUTH",
                                  "--gt " + kSample + ":GROUND_TRUTH --est " + kSample}) {
    const auto r = driftlab("eval " + args);
    EXPECT_EQ(r.code, 2) << args;
    const std::string option = args.find("--est " + kSample + ":") != std::string::npos ? "--gt" : "--est";
    EXPECT_EQ(r.err, "driftlab: " + kSample + ": an LCM event log: name the channel, as " + option + " " + kSample +
                         ":CHANNEL\n");
  }
}

}  // namespace
}  // namespace driftlab
