// A hostile MRPT rawlog (issue 31): a 2D scan declaring 2^31-1 ranges. MRPT's own reader resizes the scan to the
// declared count before reading a beam (18 GB for this one); `driftlab import rawlog` refuses the count first.
// The file is written by MRPT's own serializer, its count patched where two serializations differ.
#include <gtest/gtest.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/serialization/CArchive.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "tests/test_util.h"

namespace driftlab {
namespace {

const std::string kDriftlab = std::string(DRIFTLAB_BIN_DIR) + "/driftlab";

/// An odometry observation, then a scan of `beams` beams, as MRPT writes an observations-only rawlog.
std::vector<uint8_t> mrpt_rawlog(size_t beams) {
  mrpt::io::CMemoryStream m;
  auto out = mrpt::serialization::archiveFrom(m);
  mrpt::obs::CObservationOdometry odo;
  odo.timestamp = mrpt::Clock::fromDouble(1000.0);
  odo.odometry = mrpt::poses::CPose2D(1, 2, 0.5);
  out << odo;
  mrpt::obs::CObservation2DRangeScan scan;
  scan.timestamp = mrpt::Clock::fromDouble(1000.1);
  scan.sensorLabel = "LASER";
  scan.resizeScan(beams);
  for (size_t i = 0; i < beams; ++i) {
    scan.setScanRange(i, 1.0f + static_cast<float>(i));
    scan.setScanRangeValidity(i, true);
  }
  out << scan;
  const auto* p = static_cast<const uint8_t*>(m.getRawBufferData());
  return {p, p + m.getTotalBytesCount()};
}

/// The peak resident size of this process's children so far, in MiB (each test runs in a process of its own).
long children_peak_mib() {
  rusage u{};
  getrusage(RUSAGE_CHILDREN, &u);
  return u.ru_maxrss / 1024;
}

TEST(HostileRawlog, AScanDeclaringBillionsOfRangesIsRefusedBeforeItIsAllocated) {
  test::TempDir dir;
  // The count's offset: where a scan of 5 beams and one of 6 first differ (MRPT writes the count little-endian,
  // right before the beams).
  const auto five = mrpt_rawlog(5), six = mrpt_rawlog(6);
  size_t at = 0;
  while (at < five.size() && five[at] == six[at]) ++at;
  ASSERT_LT(at + 4, five.size());
  ASSERT_EQ(five[at], 5);
  ASSERT_EQ(five[at + 1] | five[at + 2] | five[at + 3], 0);
  auto hostile = five;
  for (int i = 0; i < 4; ++i) hostile[at + static_cast<size_t>(i)] = i == 3 ? 0x7f : 0xff;  // 2^31 - 1
  const std::string in = dir.file("hostile.rawlog"), out = dir.file("out.lcm");
  test::write_file(in, hostile);
  // What -o names already is kept: the import writes OUT.partial and renames it only when complete.
  test::write_file(out, {'k', 'e', 'e', 'p'});

  // The honest file imports (the odometry and the scan): the count's offset is the count's.
  test::write_file(dir.file("honest.rawlog"), five);
  const auto honest =
      test::run_capture(kDriftlab + " import rawlog " + dir.file("honest.rawlog") + " -o " + dir.file("honest.lcm"));
  ASSERT_EQ(honest.code, 0) << honest.err;
  EXPECT_EQ(test::read_all(dir.file("honest.lcm")).size(), 3u);  // ODOM, TF_STATIC, SCAN

  const auto start = std::chrono::steady_clock::now();
  const auto r = test::run_capture("timeout 60 " + kDriftlab + " import rawlog " + in + " -o " + out);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find(in + ": entry 1 (byte "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("declaring 2147483647 ranges (its count at byte " + std::to_string(at) + " uncompressed)"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_EQ(test::read_file(out), (std::vector<uint8_t>{'k', 'e', 'e', 'p'}));
  EXPECT_FALSE(std::filesystem::exists(out + ".partial"));
  // MRPT's reader resized the scan to 2^31-1 beams (18 GB) and died in its allocator. Refused at the count, the
  // import holds MRPT's libraries and a few small buffers: the larger of the two imports so far peaks at 91 MiB
  // in release (0.4 s), 170 MiB under ASan (1.3 s); 300 MiB tells that from any allocation for the count
  // (2^31-1 floats alone are 8 GiB; the bound is 1 GB). 30 s is the bound, for the slowest
  // (sanitized, loaded) runner.
  std::printf("import rawlog, a scan declaring 2^31-1 ranges: %.2f s, peak %ld MiB\n", seconds, children_peak_mib());
  EXPECT_LT(children_peak_mib(), 300) << "MiB";
  EXPECT_LT(seconds, 30);

  // A count within the bound that the stream does not carry ends at the stream's end, read a block at a time.
  for (int i = 0; i < 4; ++i) hostile[at + static_cast<size_t>(i)] = i == 2 ? 0x10 : 0;  // 2^20, the most allowed
  test::write_file(in, hostile);
  const auto cut = test::run_capture("timeout 60 " + kDriftlab + " import rawlog " + in + " -o " + out);
  EXPECT_EQ(cut.code, 2) << cut.err;
  EXPECT_NE(cut.err.find(in + ": entry 1"), std::string::npos) << cut.err;
  EXPECT_NE(cut.err.find("truncated"), std::string::npos) << cut.err;
  EXPECT_EQ(test::read_file(out), (std::vector<uint8_t>{'k', 'e', 'e', 'p'}));
}

}  // namespace
}  // namespace driftlab
