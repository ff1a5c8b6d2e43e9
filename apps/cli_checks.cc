#include "apps/cli_checks.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>

#include "apps/cli_util.h"

namespace driftlab::apps {

bool JsonOutput::emit(const std::string& text) const {
  if (!file.empty() && !write_output(file, text)) return false;
  return !print || file == "-" || write_output("-", text);
}

void add_json_options(CLI::App* cmd, JsonOutput* out, const std::string& what) {
  cmd->add_flag("--json", out->print, "Print " + what + " as one JSON object instead of text");
  cmd->add_option("--json-out", out->file, "Also write " + what + " as JSON to this file ('-': standard output)")
      ->type_name("FILE");
}

std::string interval(const config::Range& r) {
  const auto bound = [](double v) {
    return std::isfinite(v) ? config::format_number(v) : std::string(v < 0 ? "-inf" : "inf");
  };
  return std::string(r.min_open || !std::isfinite(r.min) ? "(" : "[") + bound(r.min) + ", " + bound(r.max) +
         (r.max_open || !std::isfinite(r.max) ? ")" : "]");
}

CLI::Validator in_range(config::Range r, const std::string& unit) {
  return CLI::Validator(
      [r, unit](std::string& text) -> std::string {
        char* end = nullptr;
        errno = 0;
        const double d = std::strtod(text.c_str(), &end);
        if (end == text.c_str() || *end != '\0') return "";  // not a number: the option's conversion says so
        if (!std::isfinite(d)) return "must be a finite number, got " + config::quoted(text);
        const std::string why = r.violation(d, unit);
        return why.empty() ? "" : why + ", got " + config::quoted(text);
      },
      interval(r), kRangeCheck);
}

}  // namespace driftlab::apps
