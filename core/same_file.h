// Refusing to write an output over one of the inputs it is made from (`replay X.lcm -o X.lcm` would destroy X.lcm
// before reading it). Compared by device and inode, not by name, so links and other spellings are caught.
#pragma once

#include <sys/stat.h>

#include <string>
#include <vector>

#include "core/result.h"

namespace driftlab {

/// An error naming both when `output` (an existing file) is the same file as one of `inputs`; ok otherwise (a
/// missing output, or "-" for standard output, is never an input).
inline Status refuse_same_file(const std::string& output, const std::vector<std::string>& inputs,
                               const std::string& option = "-o") {
  struct stat out {};
  if (output.empty() || output == "-" || ::stat(output.c_str(), &out) != 0) return {};
  for (const auto& in : inputs) {
    struct stat st {};
    if (::stat(in.c_str(), &st) == 0 && st.st_dev == out.st_dev && st.st_ino == out.st_ino) {
      return Error{option + " " + output + ": is the input " + in + "; writing it would destroy what is read"};
    }
  }
  return {};
}

}  // namespace driftlab
