#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>

#include "core/log_reader.h"

namespace driftlab::test {

TempDir::TempDir() {
  std::string tmpl = (std::filesystem::temp_directory_path() / "driftlab-test-XXXXXX").string();
  if (mkdtemp(tmpl.data()) == nullptr) std::abort();
  path_ = tmpl;
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

std::string shared_data(const std::string& relative) {
#ifdef DRIFTLAB_SHARED_DATA
  const std::string path = std::string(DRIFTLAB_SHARED_DATA) + "/" + relative;
#else
  const std::string path = "../shared/data/" + relative;
#endif
  if (std::filesystem::exists(path)) return path;
  const char* ci = std::getenv("CI");
  if (ci != nullptr && std::string(ci) == "true") {
    ADD_FAILURE() << "shared data missing under CI: " << path;
  } else {
    [&] { GTEST_SKIP() << "shared data missing: " << path; }();
  }
  return "";
}

CarmenRun carmen_run(const std::string& name) {
  CarmenRun r{shared_data("carmen/" + name + ".orig.bag"), shared_data("carmen/" + name + "-corrected.log.gz"),
              shared_data("carmen/" + name + ".relations")};
  return r.empty() ? CarmenRun{} : r;
}

std::vector<uint8_t> read_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

void write_file(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream f(path, std::ios::binary);
  f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

std::vector<uint8_t> payload(uint64_t seed, size_t size) {
  std::mt19937_64 rng(seed);
  std::vector<uint8_t> out(size);
  for (auto& b : out) b = static_cast<uint8_t>(rng());
  for (size_t i = 0; i + 4 <= size; i += 97) {
    out[i] = 0xED;
    out[i + 1] = 0xA1;
    out[i + 2] = 0xDA;
    out[i + 3] = 0x01;
  }
  return out;
}

std::vector<OwnedEvent> without_offsets(std::vector<OwnedEvent> events) {
  for (auto& e : events) e.offset = 0;
  return events;
}

namespace {
std::vector<OwnedEvent> drain(Result<LogReader> reader) {
  std::vector<OwnedEvent> out;
  EXPECT_TRUE(reader.ok()) << (reader.ok() ? "" : reader.error().message);
  if (!reader.ok()) return out;
  Event e;
  while (reader->next(e)) {
    out.push_back({e.event_number, e.utime, std::string(e.channel), {e.data.begin(), e.data.end()}, e.offset});
  }
  return out;
}
ReadOptions collecting(std::vector<Problem>* problems) {
  ReadOptions o;
  if (problems != nullptr) o.on_problem = [problems](const Problem& p) { problems->push_back(p); };
  return o;
}
}  // namespace

std::vector<OwnedEvent> read_all(const std::string& path, std::vector<Problem>* problems) {
  return drain(LogReader::open(path, collecting(problems)));
}

std::vector<std::pair<std::string, std::vector<uint8_t>>> messages_on(const std::string& path,
                                                                      const std::string& prefix) {
  std::vector<std::pair<std::string, std::vector<uint8_t>>> out;
  for (auto& e : read_all(path)) {
    if (e.channel.rfind(prefix, 0) == 0) out.emplace_back(e.channel, std::move(e.data));
  }
  return out;
}

std::vector<OwnedEvent> read_all_memory(const std::vector<uint8_t>& bytes, std::vector<Problem>* problems) {
  return drain(LogReader::from_memory(bytes, collecting(problems)));
}

int run(const std::string& command, std::string* out) {
  FILE* p = popen(command.c_str(), "r");
  if (p == nullptr) return -1;
  std::string text;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof(buf), p)) > 0) text.append(buf, n);
  const int status = pclose(p);
  if (out != nullptr) *out = std::move(text);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

CmdResult run_capture(const std::string& command) {
  TempDir dir;
  CmdResult r;
  r.code = run(command + " 2>" + dir.file("err"), &r.out);
  const auto err = read_file(dir.file("err"));
  r.err.assign(err.begin(), err.end());
  return r;
}

}  // namespace driftlab::test
