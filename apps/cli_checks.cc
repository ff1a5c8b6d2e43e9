#include "apps/cli_checks.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>

#include "apps/cli_util.h"
#include "core/same_file.h"

namespace driftlab::apps {

bool JsonOutput::emit(const std::string& text) const {
  if (!file.empty() && !write_output(file, text)) return false;
  return !print || file == "-" || write_output("-", text);
}

Status JsonOutput::check(const std::vector<std::string>& inputs, const std::vector<std::string>& outputs) const {
  if (Status s = refuse_same_file(file, inputs, "--json-out"); !s) return s;
  if (file.empty() || file == "-") return {};
  std::error_code ec;
  const auto where = std::filesystem::weakly_canonical(file, ec);
  for (const auto& out : outputs) {
    if (out.empty() || out == "-") continue;
    std::error_code ec2;
    if (!ec && where == std::filesystem::weakly_canonical(out, ec2) && !ec2) {
      return Error{"--json-out " + file + ": is also where the command writes " + out + ": give another file"};
    }
  }
  return {};
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
