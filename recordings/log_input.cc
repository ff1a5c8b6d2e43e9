#include "recordings/log_input.h"
#include "analyzers/flight_log_pair.h"
#include "analyzers/trajectory_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <vector>

#include "core/log_reader.h"
#include "core/number_text.h"
#include "core/text_file.h"
#include "formats/import.h"

namespace driftlab::recordings {
namespace {

namespace fs = std::filesystem;

/// Bumped whenever `driftlab import` writes a recording differently, so older conversions are made again.
constexpr int kCacheVersion = 4;
constexpr int kProblemLines = 20;

bool is_dir(const std::string& p) {
  std::error_code ec;
  return fs::is_directory(p, ec);
}

/// A digest of a file's content where edits show, without reading all of it: its first and last 64 KiB and 32
/// blocks of 4 KiB spread evenly between (FNV-1a, 64 bits). With the size and the change time (which no one can set
/// back, unlike the modification time) it tells an edited recording from the one converted.
std::string content_digest(int fd, int64_t size) {
  uint64_t h = 1469598103934665603ull;
  std::vector<unsigned char> buf(size_t{64} * 1024);
  auto hash_at = [&](int64_t at, size_t n) {
    if (at < 0 || at >= size) return;
    n = static_cast<size_t>(std::min<int64_t>(static_cast<int64_t>(n), size - at));
    const ssize_t got = ::pread(fd, buf.data(), n, at);
    for (ssize_t i = 0; i < got; ++i) h = (h ^ buf[static_cast<size_t>(i)]) * 1099511628211ull;
    h = (h ^ static_cast<uint64_t>(got)) * 1099511628211ull;
  };
  hash_at(0, buf.size());
  for (int i = 1; i <= 32; ++i) hash_at(size / 33 * i, 4096);
  hash_at(std::max<int64_t>(0, size - static_cast<int64_t>(buf.size())), buf.size());
  char tag[20];
  std::snprintf(tag, sizeof(tag), "%016llx", static_cast<unsigned long long>(h));
  return tag;
}

/// One file's identity: size, modification and change times, device and inode, owner, content digest; empty when
/// it cannot be opened. With no_follow a symbolic link is not opened (an error), nor anything but a regular file.
std::string file_identity(const std::string& path, bool no_follow) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | (no_follow ? O_NOFOLLOW : 0));
  if (fd < 0) return {};
  struct stat st {};
  std::string out;
  if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode)) {
    std::ostringstream o;
    o << st.st_size << " " << st.st_mtim.tv_sec << "." << st.st_mtim.tv_nsec << " " << st.st_ctim.tv_sec << "."
      << st.st_ctim.tv_nsec << " " << st.st_dev << ":" << st.st_ino << " " << st.st_uid << " "
      << content_digest(fd, st.st_size);
    out = o.str();
  }
  ::close(fd);
  return out;
}

/// What identifies the recording's files: if any of them changed, the conversion is stale.
std::string identity(const std::vector<std::string>& inputs) {
  std::vector<std::string> files = formats::recording_files(inputs);
  if (inputs.size() == 1 && is_dir(inputs[0])) files.push_back(inputs[0] + "/metadata.yaml");
  std::ostringstream o;
  o << "driftlab import cache " << kCacheVersion << "\n";
  for (const auto& f : files) {
    std::error_code ec;
    const std::string abs = fs::absolute(f, ec).string();
    const std::string id = file_identity(f, false);
    if (id.empty()) {
      o << "missing " << abs << "\n";
      continue;
    }
    o << "file " << id << " " << abs << "\n";
  }
  return o.str();
}

/// Why the cache file (or its key) at path cannot be trusted: a symbolic link, not a regular file, someone
/// else's; empty when it can.
std::string untrusted(const std::string& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) return "missing";
  if (S_ISLNK(st.st_mode)) return "a symbolic link";
  if (!S_ISREG(st.st_mode)) return "not a regular file";
  if (st.st_uid != ::geteuid()) return "owned by another user";
  return {};
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
  // A file's name holds 255 bytes, and the cache's own files add up to 40 (".key.partial.PID.N", ".dlidx"): a
  // recording with a long name was refused ("File name too long"). Such a name is cut and its hash appended.
  const size_t slash = p.rfind('/');
  const size_t name_at = slash == std::string::npos ? 0 : slash + 1;
  if (constexpr size_t kMaxName = 160; p.size() - name_at > kMaxName) {
    uint64_t h = 1469598103934665603ull;  // FNV-1a of the whole name
    for (size_t i = name_at; i < p.size(); ++i) h = (h ^ static_cast<unsigned char>(p[i])) * 1099511628211ull;
    char tag[20];
    std::snprintf(tag, sizeof(tag), "%016llx", static_cast<unsigned long long>(h));
    p = p.substr(0, name_at + 100) + "~" + tag;
  }
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
      return Error(in +
                   ": several files make one recording only for bags and MCAP files, or a flight log (ULog) "
                   "beside a bag (this is " +
                   (d.format == formats::Format::kLcmLog ? std::string("an LCM log") : d.description) + ")");
    }
  }
  const std::string key = identity(inputs);
  std::string cache = import_cache_path(inputs);
  if (!writable_dir(fs::path(cache).parent_path().string())) {
    const std::string beside = cache;
    cache = fallback_path(inputs, beside);
    if (cache.empty()) {
      return Error(inputs[0] + kCannotWriteConversion + beside + ": the folder is read-only, and ~/.cache/driftlab too",
                   ErrorCode::kCannotWrite);
    }
  }
  const std::string key_path = cache + ".key";
  const std::string named =
      inputs[0] + (inputs.size() > 1 ? " (and " + std::to_string(inputs.size() - 1) + " more)" : "");
  // The key says what recording the conversion was made from and what the conversion itself was when written: a
  // key or a conversion that is a symbolic link, someone else's, or not the file the key recorded (an output
  // written over it, a copy of another log) is not believed, and the recording is converted again.
  const std::string key_doubt = untrusted(key_path);
  const std::string old = key_doubt.empty() ? read_text(key_path) : std::string();
  const std::string cache_doubt = untrusted(cache);
  std::string recorded_cache;
  if (const size_t at = old.find("\ncache ", key.size() > 0 ? key.size() - 1 : 0); at != std::string::npos) {
    const size_t end = old.find('\n', at + 1);
    recorded_cache = old.substr(at + 7, end == std::string::npos ? std::string::npos : end - at - 7);
  }
  const bool same_recording = old.starts_with(key);
  if (same_recording && cache_doubt.empty() && !recorded_cache.empty() &&
      file_identity(cache, true) == recorded_cache) {
    int64_t problems = 0;
    if (const size_t at = old.find("problems ", key.size()); at != std::string::npos) {
      problems = std::strtoll(old.c_str() + at + 9, nullptr, 10);
    }
    std::fprintf(stderr, "driftlab: %s: reading its conversion %s%s\n", named.c_str(), cache.c_str(),
                 problems
                     ? (" (" + thousands(problems) + " problems when converted; `driftlab import` lists them)").c_str()
                     : "");
    // A flight log beside a bag: how it was put on the bag's clock, said on every use as when converted.
    if (const size_t at = old.find("\nalignment ", key.size() > 0 ? key.size() - 1 : 0); at != std::string::npos) {
      const size_t end = old.find('\n', at + 1);
      std::fprintf(stderr, "driftlab: %s\n",
                   old.substr(at + 11, end == std::string::npos ? end : end - at - 11).c_str());
    }
    return cache;
  }
  if (same_recording) {
    std::fprintf(stderr, "driftlab: %s: its conversion %s is %s; converting it again\n", named.c_str(), cache.c_str(),
                 !cache_doubt.empty() ? cache_doubt.c_str() : "not the file made then (replaced or changed since)");
  }
  std::fprintf(stderr, "driftlab: %s: converting it to %s (kept for later runs)\n", named.c_str(), cache.c_str());
  ProblemLines problems(named);
  std::string alignment;
  auto summary = analyzers::import_recording(inputs, cache, std::ref(problems), &alignment);
  if (!summary) {
    // Writing the conversion failed (a full disk): an I/O failure, named by the input and the cache, not by the
    // partial file, which is gone. Anything else is the recording's.
    const std::string& m = summary.error().message;
    if (summary.error().code == ErrorCode::kCannotWrite) {
      const size_t colon = m.find(": ");
      return Error(
          named + kCannotWriteConversion + cache + (colon == std::string::npos ? std::string() : m.substr(colon)),
          ErrorCode::kCannotWrite);
    }
    return summary.error();
  }
  problems.finish();
  std::fprintf(stderr, "driftlab: %s (%s): %s messages converted\n", named.c_str(), summary->format.c_str(),
               thousands(summary->messages).c_str());
  if (!alignment.empty()) std::fprintf(stderr, "driftlab: %s\n", alignment.c_str());
  // The key last, written beside and renamed: a conversion cut short is never taken for a whole one. It records the
  // conversion as written, so that anything put in its place later is noticed.
  const std::string made = file_identity(cache, true);
  if (made.empty())
    return Error(named + kCannotWriteConversion + cache + ": cannot read it back", ErrorCode::kCannotWrite);
  if (Status s = write_file_atomically(key_path,
                                       key + "cache " + made + "\nproblems " + std::to_string(problems.count()) + "\n" +
                                           (alignment.empty() ? std::string() : "alignment " + alignment + "\n"),
                                       {.partial_of_its_own = true});
      !s) {
    return Error(named + kCannotWriteConversion + cache + ": " + s.message(), ErrorCode::kCannotWrite);
  }
  return cache;
}

Result<std::string> event_log_for(const std::vector<std::string>& inputs) {
  auto log = log_for(inputs);
  if (!log) return log;
  if (Status s = check_event_log(*log); !s) return s.error();
  return log;
}

Result<std::string> log_channel_for(const std::string& source) {
  std::string log, channel;
  if (!analyzers::split_log_channel(source, &log, &channel)) return source;
  if (!formats::is_importable(formats::detect_format(log).format)) return source;
  auto converted = log_for(log);
  if (!converted) return converted.error();
  return *converted + ":" + channel;
}

void ProblemLines::operator()(const std::string& line) {
  if (count_++ < kProblemLines) std::fprintf(stderr, "driftlab: %s\n", line.c_str());
}

void ProblemLines::finish() const {
  if (count_ > kProblemLines) {
    std::fprintf(stderr, "driftlab: %s: %s more problems\n", named_.c_str(), thousands(count_ - kProblemLines).c_str());
  }
}

}  // namespace driftlab::recordings
