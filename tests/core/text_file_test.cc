// core/text_file.h: reading a whole text file a user names; writing one whole or not at all.
#include "core/text_file.h"

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <thread>
#include <vector>

#include "tests/test_util.h"

namespace driftlab {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> partial_files(const std::string& dir) {
  std::vector<std::string> out;
  for (const auto& f : fs::directory_iterator(dir)) {
    if (f.path().filename().string().find(".partial") != std::string::npos) out.push_back(f.path().string());
  }
  return out;
}

TEST(WriteFileAtomically, ReplacesTheFileWholeOrLeavesItAsItWas) {
  test::TempDir dir;
  const std::string path = dir.file("out.json");
  ASSERT_TRUE(write_file_atomically(path, "first\n"));
  ASSERT_TRUE(write_file_atomically(path, "second\n", kSynced));
  EXPECT_EQ(read_text_file(path, "output").value(), "second\n");

  // A folder in the way of the rename: the error names the path, says it cannot write (the environment's fault:
  // the commands exit 1 on it, not 2), and leaves no partial file.
  fs::create_directories(dir.file("in-the-way/x"));
  const Status blocked = write_file_atomically(dir.file("in-the-way"), "text");
  ASSERT_FALSE(blocked);
  EXPECT_EQ(blocked.message().rfind(dir.file("in-the-way") + ": cannot write: ", 0), 0u) << blocked.message();
  EXPECT_EQ(blocked.code(), ErrorCode::kCannotWrite);

  // A folder that is a file: the partial file cannot even be created.
  const Status no_folder = write_file_atomically(path + "/child", "text");
  ASSERT_FALSE(no_folder);
  EXPECT_EQ(no_folder.message(), path + "/child: cannot write: Not a directory");
  EXPECT_EQ(no_folder.code(), ErrorCode::kCannotWrite);
  EXPECT_EQ(read_text_file(path, "output").value(), "second\n");
  EXPECT_EQ(partial_files(dir.path()), std::vector<std::string>{});
}

TEST(WriteFileAtomically, WritersOfOnePathAtOnceEachRenameAWholeFileOfTheirOwn) {
  // Processes indexing or converting one log at once write its cache together. Through a shared PATH.partial one
  // truncated the file another was writing and renamed its half into place; with a partial file of its own each
  // renames a whole file, so the file is always one writer's text, whole.
  test::TempDir dir;
  const std::string path = dir.file("cache");
  constexpr int kWriters = 8, kRounds = 50;
  std::vector<std::string> texts;
  texts.reserve(kWriters);
  for (int w = 0; w < kWriters; ++w) texts.push_back(std::string(4096 + w * 1000, static_cast<char>('a' + w)));
  std::vector<std::thread> writers;
  writers.reserve(kWriters);
  std::atomic<int> failures{0};
  for (int w = 0; w < kWriters; ++w) {
    writers.emplace_back([&, w] {
      for (int r = 0; r < kRounds; ++r) {
        if (!write_file_atomically(path, texts[w], {.partial_of_its_own = true})) ++failures;
      }
    });
  }
  bool torn = false;
  for (int r = 0; r < 200; ++r) {
    std::ifstream in(path, std::ios::binary);
    const std::string seen((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (!seen.empty() && std::find(texts.begin(), texts.end(), seen) == texts.end()) torn = true;
  }
  for (auto& t : writers) t.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_FALSE(torn);
  const std::string last = read_text_file(path, "cache").value();
  EXPECT_NE(std::find(texts.begin(), texts.end(), last), texts.end());
  EXPECT_EQ(partial_files(dir.path()), std::vector<std::string>{});
}

TEST(CreatePartialOfItsOwn, GivesEachCallAFileOfItsOwnBesideThePath) {
  test::TempDir dir;
  const std::string path = dir.file("out.lcm");
  auto a = create_partial_of_its_own(path), b = create_partial_of_its_own(path);
  ASSERT_TRUE(a);
  ASSERT_TRUE(b);
  EXPECT_NE(a->path, b->path);
  EXPECT_EQ(a->path.rfind(path + ".partial.", 0), 0u) << a->path;
  EXPECT_TRUE(fs::is_regular_file(a->path));
  ::close(a->fd);
  ::close(b->fd);
  auto bad = create_partial_of_its_own(dir.file("absent/out.lcm"));
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().code, ErrorCode::kCannotWrite);
  EXPECT_NE(bad.error().message.find("No such file or directory"), std::string::npos) << bad.error().message;
}

TEST(ReadTextFile, RefusesWhatIsNotARegularFileAtOnce) {
  test::TempDir dir;
  const Status folder = read_text_file(dir.path(), "config").error();
  EXPECT_EQ(folder.message(), dir.path() + ": the config: not a regular file (a FIFO, device, socket or folder)");
  EXPECT_EQ(read_text_file(dir.file("absent.yaml"), "config").error().message,
            dir.file("absent.yaml") + ": cannot open the config: No such file or directory");
}

}  // namespace
}  // namespace driftlab
