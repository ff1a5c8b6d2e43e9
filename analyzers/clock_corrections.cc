#include "analyzers/clock_corrections.h"

#include <cstdio>
#include <cstdlib>
#include <optional>

#include "core/number_text.h"

namespace driftlab::analyzers {

ClockCorrections clock_corrections(const Diagnosis& d, std::vector<std::string>* notes) {
  ClockCorrections r;
  char buf[320];
  for (const auto& c : d.channels) {
    if (!c.clock_valid) continue;
    // On a clock of another epoch (simulation time) the clock was fitted to the stamps mapped onto the recorder's:
    // no offset of the source's own to correct.
    if (c.domain >= 0 && d.domains[static_cast<size_t>(c.domain)].mapped) continue;
    const bool ahead = clock_ahead(c.clock_offset_s);
    const bool drifts = clock_drifts(c.clock_drift_ppm);
    if (!ahead && !drifts) continue;
    // Only what the diagnosis is sure of: a correction whose 95% interval reaches zero could be jitter, and
    // applying it could make things worse (a wrong shift skews this stream against every other).
    const bool sure_ahead = ahead && c.clock_offset_ci_s[0] > 0;
    const bool sure_drift = drifts && (c.clock_drift_ci_ppm[0] > 0 || c.clock_drift_ci_ppm[1] < 0);
    if (!sure_ahead && !sure_drift) {
      if (notes != nullptr) {
        std::snprintf(buf, sizeof(buf), "not restamping %s: %+.1f ms (95%%: %+.1f to %+.1f), %+.0f ppm (95%%: %+.0f to "
                      "%+.0f) could be zero", c.name.c_str(), c.clock_offset_s * 1e3, c.clock_offset_ci_s[0] * 1e3,
                      c.clock_offset_ci_s[1] * 1e3, c.clock_drift_ppm, c.clock_drift_ci_ppm[0], c.clock_drift_ci_ppm[1]);
        notes->push_back(buf);
      }
      continue;
    }
    const ClockCorrection k{sure_ahead ? c.clock_offset_s : 0.0, sure_drift ? c.clock_drift_ppm : 0.0, d.start_utime};
    r[c.name] = k;
    if (notes != nullptr) {
      std::snprintf(buf, sizeof(buf), "restamp %s: %+.1f ms, %+.0f ppm (from the timing diagnosis of %s: offset 95%% "
                    "%+.1f to %+.1f ms, drift %+.0f to %+.0f ppm)", c.name.c_str(), k.offset_s * 1e3, k.drift_ppm,
                    d.log.c_str(), c.clock_offset_ci_s[0] * 1e3, c.clock_offset_ci_s[1] * 1e3,
                    c.clock_drift_ci_ppm[0], c.clock_drift_ci_ppm[1]);
      notes->push_back(buf);
    }
  }
  return r;
}

std::map<std::string, Duration> command_retiming(const Diagnosis& d, std::vector<std::string>* notes) {
  std::map<std::string, Duration> out;
  char buf[320];
  for (const CommandLoop& loop : d.command_loops) {
    if (!loop.delay_valid) continue;
    const bool sure = loop.confidence >= kConfidentCorrelation;
    if (loop.delay_s >= kRetimeDelayMin_s && sure) {
      out[loop.command_channel] = Duration::from_seconds_rounded(loop.delay_s);
      std::snprintf(buf, sizeof(buf),
                    "retime %s: each command starts %.1f ms before it arrived (the delay from "
                    "command to motion the diagnosis of %s measured, agreement %.2f)",
                    loop.command_channel.c_str(), loop.delay_s * 1e3, d.log.c_str(), loop.confidence);
    } else {
      std::snprintf(buf, sizeof(buf), "not retiming %s: %.1f ms from command to motion%s", loop.command_channel.c_str(),
                    loop.delay_s * 1e3, sure ? " is the controller's own lag" : ", measured with too little agreement");
    }
    if (notes != nullptr) notes->push_back(buf);
  }
  return out;
}

Result<CorrectionPlan> plan_corrections(const std::vector<std::string>& logs, bool clocks_from_diagnosis,
                                        const std::vector<std::string>& retime) {
  CorrectionPlan plan;
  std::vector<std::optional<Diagnosis>> diagnoses(logs.size());
  auto diagnosed = [&](size_t i) -> Result<const Diagnosis*> {
    if (!diagnoses[i]) {
      auto d = diagnose(logs[i]);
      if (!d) return d.error();
      diagnoses[i] = std::move(*d);
    }
    return &*diagnoses[i];
  };
  if (clocks_from_diagnosis) {
    for (size_t i = 0; i < logs.size(); ++i) {
      auto d = diagnosed(i);
      if (!d) return d.error();
      plan.clocks.merge(clock_corrections(**d, &plan.notes));
    }
  }
  for (const std::string& r : retime) {
    if (r == "auto") {
      for (size_t i = 0; i < logs.size(); ++i) {
        auto d = diagnosed(i);
        if (!d) return d.error();
        for (const auto& [channel, delay] : command_retiming(**d, &plan.notes)) plan.retime[channel] = delay;
      }
      continue;
    }
    const auto eq = r.find('=');
    char* end = nullptr;
    const double s = eq == std::string::npos ? 0 : std::strtod(r.c_str() + eq + 1, &end);
    if (eq == std::string::npos || eq == 0 || end == r.c_str() + eq + 1 || *end != '\0' || !(s >= 0 && s <= 3600)) {
      return Error{"--retime " + r + ": expected auto or CHANNEL=SECONDS (0..3600)"};
    }
    plan.retime[r.substr(0, eq)] = Duration::from_seconds_rounded(s);
    plan.notes.push_back("retime " + r.substr(0, eq) + ": each command starts " + short_number(s) +
                         " s before it arrived (--retime)");
  }
  return plan;
}

}  // namespace driftlab::analyzers
