#include "runtime/module_report.h"

#include <cmath>
#include <cstdio>
#include <map>

#include "core/number_text.h"

namespace driftlab::runtime {

nlohmann::json to_json(const std::vector<ModuleReport>& reports) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& m : reports) {
    out.push_back({{"name", m.name},
                   {"inputs", m.inputs},
                   {"late", m.late},
                   {"out_of_order", m.out_of_order},
                   {"dropped", m.dropped},
                   {"outputs", m.outputs},
                   {"proc_mean_s", m.proc_mean_s},
                   {"proc_p95_s", m.proc_p95_s},
                   {"proc_max_s", m.proc_max_s},
                   {"queue_depth_max", m.queue_depth_max},
                   {"warnings", m.warnings},
                   {"metrics", nlohmann::json(std::map<std::string, double>(m.metrics.begin(), m.metrics.end()))}});
  }
  return out;
}

Result<std::vector<ModuleReport>> module_reports_from_json(const nlohmann::json& run) {
  std::vector<ModuleReport> out;
  try {
    for (const auto& j : run.at("modules")) {
      ModuleReport m;
      j.at("name").get_to(m.name);
      j.at("inputs").get_to(m.inputs);
      j.at("late").get_to(m.late);
      j.at("out_of_order").get_to(m.out_of_order);
      j.at("dropped").get_to(m.dropped);
      j.at("outputs").get_to(m.outputs);
      j.at("proc_mean_s").get_to(m.proc_mean_s);
      j.at("proc_p95_s").get_to(m.proc_p95_s);
      j.at("proc_max_s").get_to(m.proc_max_s);
      j.at("queue_depth_max").get_to(m.queue_depth_max);
      j.at("warnings").get_to(m.warnings);
      for (const auto& [name, v] : j.at("metrics").items()) m.metrics.emplace_back(name, v.get<double>());
      out.push_back(std::move(m));
    }
  } catch (const nlohmann::json::exception& e) {
    return Error{std::string("not the module reports of driftlab replay --json: ") + e.what()};
  }
  return out;
}

std::optional<double> metric(const ModuleReport& report, std::string_view name) {
  for (const auto& [key, value] : report.metrics) {
    if (key == name) return value;
  }
  return std::nullopt;
}

std::string module_report_text(const std::vector<ModuleReport>& reports, bool timing) {
  std::string out;
  char buf[256];
  for (const auto& m : reports) {
    std::snprintf(buf, sizeof(buf), "  %-10s %s inputs (%s late, %s out of order, %s dropped), %s outputs",
                  m.name.c_str(), thousands(m.inputs).c_str(), thousands(m.late).c_str(),
                  thousands(m.out_of_order).c_str(), thousands(m.dropped).c_str(), thousands(m.outputs).c_str());
    out += buf;
    if (timing) {
      std::snprintf(buf, sizeof(buf), ", %.3f ms per input (p95 %.3f ms), queue <= %d", m.proc_mean_s * 1e3,
                    m.proc_p95_s * 1e3, m.queue_depth_max);
      out += buf;
    }
    out += "\n";
    if (!m.metrics.empty()) {
      out += "            ";
      for (size_t i = 0; i < m.metrics.size(); ++i) {
        const double v = m.metrics[i].second;
        const bool whole = v == std::floor(v) && std::abs(v) < 1e15;
        std::snprintf(buf, sizeof(buf), whole ? "%s%s %.0f" : "%s%s %.4g", i > 0 ? ", " : "",
                      m.metrics[i].first.c_str(), v);
        out += buf;
      }
      out += "\n";
    }
    for (const auto& w : m.warnings) out += "  warning: " + w + "\n";
  }
  return out;
}

nlohmann::json to_json(const LiveOptions& options, const LiveReport& report, const std::vector<std::string>& notes) {
  return {
      {"url", options.url},      {"out", options.out}, {"received", report.received},       {"outputs", report.outputs},
      {"wall_s", report.wall_s}, {"notes", notes},     {"modules", to_json(report.modules)}};
}

std::string live_text(const LiveOptions& options, const LiveReport& report, const std::vector<std::string>& notes) {
  std::string out;
  for (const auto& n : notes) out += n + "\n";
  appendf(out, "ran %.1f s on %s: %s messages handled, %s module outputs%s%s\n", report.wall_s, options.url.c_str(),
          thousands(report.received).c_str(), thousands(report.outputs).c_str(), options.out.empty() ? "" : " -> ",
          options.out.c_str());
  return out + module_report_text(report.modules, true);
}

}  // namespace driftlab::runtime
