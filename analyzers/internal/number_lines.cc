#include "analyzers/internal/number_lines.h"

#include <charconv>
#include <cstdint>

namespace driftlab::analyzers::internal {
namespace {

bool is_separator(char c) { return c == ' ' || c == '\t' || c == ',' || c == '\r'; }

const char* parse_double(const char* p, const char* end, double& out) {
  static constexpr double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                                      1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
  const char* q = p;
  const bool negative = q < end && *q == '-';
  if (negative) ++q;
  uint64_t mantissa = 0;
  const char* start = q;
  while (q < end && static_cast<unsigned>(*q - '0') < 10) mantissa = mantissa * 10 + static_cast<unsigned>(*q++ - '0');
  const char* dot = q;
  if (q < end && *q == '.') {
    ++q;
    while (q < end && static_cast<unsigned>(*q - '0') < 10) mantissa = mantissa * 10 + static_cast<unsigned>(*q++ - '0');
  }
  const long decimals = q > dot ? q - dot - 1 : 0;
  const long digits = q - start - (q > dot ? 1 : 0);  // at most 19 digits cannot overflow 64 bits
  const bool plain = digits > 0 && (q == end || is_separator(*q));
  if (plain && digits <= 19 && mantissa <= (uint64_t{1} << 53) && decimals <= 22) {
    const double v = static_cast<double>(mantissa) / kPow10[decimals];
    out = negative ? -v : v;
    return q;
  }
  const auto [next, ec] = std::from_chars(p, end, out);
  return ec == std::errc() ? next : nullptr;
}

}  // namespace

int parse_numbers(const char* p, const char* end, double* out, int max) {
  int n = 0;
  while (p < end) {
    while (p < end && is_separator(*p)) ++p;
    if (p >= end) break;
    if (n == max) return n + 1;
    const char* next = parse_double(p, end, out[n]);
    if (next == nullptr || next == p) return -1;
    p = next;
    ++n;
  }
  return n;
}

}  // namespace driftlab::analyzers::internal
