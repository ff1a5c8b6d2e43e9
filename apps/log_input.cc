#include "apps/log_input.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "apps/cli_util.h"
#include "core/log_reader.h"
#include "formats/import.h"

namespace driftlab::apps {
namespace {

namespace fs = std::filesystem;

/// Bumped whenever `driftlab import` writes a recording differently, so older conversions are made again.
constexpr int kCacheVersion = 3;
constexpr int kProblemLines = 20;

bool is_dir(const std::string& p) {
  std::error_code ec;
  return fs::is_directory(p, ec);
}

/// What identifies the recording's files: if any of them changed, the conversion is stale.
std::string identity(const std::vector<std::string>& inputs) {
  std::vector<std::string> files = formats::recording_files(inputs);
  if (inputs.size() == 1 && is_dir(inputs[0])) files.push_back(inputs[0] + "/metadata.yaml");
  std::ostringstream o;
  o << "driftlab import cache " << kCacheVersion << "\n";
  for (const auto& f : files) {
    struct stat st {};
    std::error_code ec;
    const std::string abs = fs::absolute(f, ec).string();
    if (::stat(f.c_str(), &st) != 0) {
      o << "missing " << abs << "\n";
      continue;
    }
    o << "file " << st.st_size << " " << st.st_mtim.tv_sec << "." << st.st_mtim.tv_nsec << " " << st.st_ino << " "
      << abs << "\n";
  }
  return o.str();
}

std::string read_text(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

/// Whether a file can be made in dir. Its write bits count even for root, whom access() lets write anywhere: a
/// folder someone made read-only (shared data) is left alone.
bool writable_dir(const std::string& dir) {
  const char* d = dir.empty() ? "." : dir.c_str();
  struct stat st {};
  return ::stat(d, &st) == 0 && (st.st_mode & (S_IWUSR | S_IWGRP | S_IWOTH)) != 0 && ::access(d, W_OK) == 0;
}

/// The cache under the user's cache folder, for recordings in folders that cannot be written.
std::string fallback_path(const std::vector<std::string>& inputs, const std::string& beside) {
  std::string base;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) {
    base = x;
  } else if (const char* h = std::getenv("HOME"); h && *h) {
    base = std::string(h) + "/.cache";
  } else {
    return {};
  }
  base += "/driftlab";
  std::error_code ec;
  fs::create_directories(base, ec);
  if (!writable_dir(base)) return {};
  uint64_t h = 1469598103934665603ull;  // FNV-1a of the inputs' absolute paths: one cache per recording
  for (const auto& in : inputs) {
    for (const char c : fs::absolute(in, ec).string()) h = (h ^ static_cast<unsigned char>(c)) * 1099511628211ull;
    h = (h ^ 0xff) * 1099511628211ull;
  }
  char tag[20];
  std::snprintf(tag, sizeof(tag), "%016llx", static_cast<unsigned long long>(h));
  std::string name = fs::path(beside).filename().string();
  name.resize(name.size() - std::string_view(".dlimport.lcm").size());
  return base + "/" + name + "-" + tag + ".dlimport.lcm";
}

}  // namespace

std::string import_cache_path(const std::vector<std::string>& inputs) {
  std::string first = inputs.at(0);
  while (first.size() > 1 && first.back() == '/') first.pop_back();  // "bag/" names the folder "bag"
  std::string p = first;
  if (inputs.size() > 1) p += "+" + std::to_string(inputs.size() - 1);
  return p + ".dlimport.lcm";
}

Result<std::string> log_for(const std::vector<std::string>& inputs) {
  if (inputs.empty()) return Error("no log given");
  for (const auto& in : inputs) {
    const formats::Detected d = formats::detect_format(in);
    if (d.format == formats::Format::kMrptRawlog) {
      return Error(in + ": an MRPT rawlog: convert it with `driftlab import rawlog` first");
    }
    if (!formats::is_importable(d.format)) {
      // An LCM log (or what no importer recognises) is read as an LCM log, which reports what it finds.
      if (inputs.size() == 1) return inputs[0];
      return Error(in + ": several files make one recording only for bags and MCAP files (this is " +
                   (d.format == formats::Format::kLcmLog ? std::string("an LCM log") : d.description) + ")");
    }
  }
  const std::string key = identity(inputs);
  std::string cache = import_cache_path(inputs);
  if (!writable_dir(fs::path(cache).parent_path().string())) {
    const std::string beside = cache;
    cache = fallback_path(inputs, beside);
    if (cache.empty()) return Error(beside + ": cannot write the conversion there, nor under ~/.cache/driftlab");
  }
  const std::string key_path = cache + ".key";
  const std::string named = inputs[0] + (inputs.size() > 1 ? " (and " + std::to_string(inputs.size() - 1) + " more)" : "");
  const std::string old = read_text(key_path);
  std::error_code ec;
  if (old.starts_with(key) && fs::is_regular_file(cache, ec)) {
    int64_t problems = 0;
    if (const size_t at = old.find("problems ", key.size()); at != std::string::npos) {
      problems = std::strtoll(old.c_str() + at + 9, nullptr, 10);
    }
    std::fprintf(stderr, "driftlab: %s: reading its conversion %s%s\n", named.c_str(), cache.c_str(),
                 problems ? (" (" + thousands(problems) + " problems when converted; `driftlab import` lists them)").c_str()
                          : "");
    return cache;
  }
  std::fprintf(stderr, "driftlab: %s: converting it to %s (kept for later runs)\n", named.c_str(), cache.c_str());
  int printed = 0;
  int64_t problems = 0;
  auto summary = formats::import_log(inputs, cache, [&](const std::string& line) {
    ++problems;
    if (printed++ < kProblemLines) std::fprintf(stderr, "driftlab: %s\n", line.c_str());
  });
  if (!summary) return Error(summary.error().message);
  if (problems > kProblemLines) {
    std::fprintf(stderr, "driftlab: %s: %s more problems\n", named.c_str(), thousands(problems - kProblemLines).c_str());
  }
  std::fprintf(stderr, "driftlab: %s (%s): %s messages converted\n", named.c_str(), summary->format.c_str(),
               thousands(summary->messages).c_str());
  // The key last, written beside and renamed: a conversion cut short is never taken for a whole one.
  {
    std::ofstream k(key_path + ".partial", std::ios::binary | std::ios::trunc);
    k << key << "problems " << problems << "\n";
    if (!k.flush()) return Error(key_path + ": cannot write");
  }
  if (std::rename((key_path + ".partial").c_str(), key_path.c_str()) != 0) {
    std::remove((key_path + ".partial").c_str());
    return Error(key_path + ": cannot rename into place");
  }
  return cache;
}

Result<std::string> event_log_for(const std::vector<std::string>& inputs) {
  auto log = log_for(inputs);
  if (!log) return log;
  if (Status s = check_event_log(*log); !s) return Error{s.message()};
  return log;
}

Result<std::string> log_channel_for(const std::string& source) {
  const size_t colon = source.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == source.size()) return source;
  const std::string log = source.substr(0, colon);
  std::error_code ec;
  if (!fs::exists(log, ec)) return source;
  const formats::Detected d = formats::detect_format(log);
  if (!formats::is_importable(d.format)) return source;
  auto converted = log_for(log);
  if (!converted) return converted.error();
  return *converted + source.substr(colon);
}

}  // namespace driftlab::apps
