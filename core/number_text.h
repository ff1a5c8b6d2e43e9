// Numbers as a person reads them in a line of text: the commands' output, the messages of the libraries.
// Thread-safety: pure functions.
#pragma once

#include <cstdint>
#include <string>

namespace driftlab {

/// A number as a person writes it: "2", "0.25", "1e+308" (never 309 digits).
std::string short_number(double v);

/// 1536 -> "1.5 KiB".
std::string human_bytes(double bytes);
/// 1234567 -> "1,234,567".
std::string thousands(int64_t n);

/// printf onto the end of out (a table's rows built as text).
__attribute__((format(printf, 2, 3))) void appendf(std::string& out, const char* format, ...);

}  // namespace driftlab
