// Refusing an output that would destroy what it is made from, or what is not a file at all. `replay X.lcm -o
// X.lcm` would destroy X.lcm before reading it; `import BAG -o BAG/x_0.mcap` would replace the bag's own storage
// file; `-o /dev/null` or `-o FIFO` would replace the node with a regular file, since every output is written
// beside its target and renamed into place. Checked before anything is opened for writing.
#pragma once

#include <sys/stat.h>

#include <filesystem>
#include <string>
#include <vector>

#include "core/result.h"

namespace driftlab {

/// What an output is: a file (written beside and renamed into place) or a folder (export csv, export rosbag2).
enum class OutputKind { kFile, kFolder };

namespace internal {

/// What kind of node st is, in words.
inline const char* node_kind(const struct stat& st) {
  if (S_ISCHR(st.st_mode)) return "a character device";
  if (S_ISBLK(st.st_mode)) return "a block device";
  if (S_ISFIFO(st.st_mode)) return "a FIFO";
  if (S_ISSOCK(st.st_mode)) return "a socket";
  if (S_ISDIR(st.st_mode)) return "a folder";
  if (S_ISREG(st.st_mode)) return "a regular file";
  return "not a regular file";
}

/// The absolute path with every symbolic link and "..", as far as it exists, resolved.
inline std::filesystem::path resolved(const std::string& p) {
  std::error_code ec;
  auto r = std::filesystem::weakly_canonical(std::filesystem::absolute(p, ec), ec);
  if (ec) r = std::filesystem::absolute(p, ec).lexically_normal();
  return r;
}

/// Whether `inner` is `outer` itself or lies anywhere below it.
inline bool is_within(const std::filesystem::path& inner, const std::filesystem::path& outer) {
  auto i = inner.begin();
  for (auto o = outer.begin(); o != outer.end(); ++o, ++i) {
    if (o->empty()) continue;  // a trailing separator
    if (i == inner.end() || *i != *o) return false;
  }
  return true;
}

}  // namespace internal

/// An error, one line naming the option and the path, when `output`:
///  - exists and is not a regular file (a folder for OutputKind::kFolder): a character device such as /dev/null, a
///    FIFO, a socket; outputs are written beside their target and renamed into place, which would replace the node;
///  - is the same file as one of `inputs` (by device and inode, so links and other spellings are caught);
///  - is, or lies inside, an input that is a folder (a ROS 2 bag: its storage files and metadata.yaml), by its path
///    with symbolic links resolved;
/// Ok otherwise; an empty output, or "-" for standard output, is never refused.
inline Status refuse_same_file(const std::string& output, const std::vector<std::string>& inputs,
                               const std::string& option = "-o", OutputKind kind = OutputKind::kFile) {
  if (output.empty() || output == "-") return {};
  const std::string named = option + " " + output + ": ";
  struct stat out {};
  const bool exists = ::stat(output.c_str(), &out) == 0;
  if (exists) {
    const bool fits = kind == OutputKind::kFile ? S_ISREG(out.st_mode) : S_ISDIR(out.st_mode) || S_ISREG(out.st_mode);
    if (!fits) {
      return Error{named + "is " + internal::node_kind(out) + ", not a " +
                   (kind == OutputKind::kFile ? "regular file" : "folder") +
                   "; outputs are written beside their path and renamed into place, which would replace it: give " +
                   (kind == OutputKind::kFile ? "a file's path" : "a folder's path")};
    }
  }
  const std::filesystem::path out_path = internal::resolved(output);
  for (const auto& in : inputs) {
    if (in.empty() || in == "-") continue;
    struct stat st {};
    if (::stat(in.c_str(), &st) != 0) continue;
    if (exists && st.st_dev == out.st_dev && st.st_ino == out.st_ino) {
      return Error{named + "is the input " + in + "; writing it would destroy what is read"};
    }
    const std::filesystem::path in_path = internal::resolved(in);
    if (S_ISDIR(st.st_mode) && internal::is_within(out_path, in_path)) {
      return Error{named + "is inside the input folder " + in + "; writing there would change the recording read"};
    }
  }
  return {};
}

}  // namespace driftlab
