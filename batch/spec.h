// Reading sweep and batch specs (docs/batch.md): a spec file read through its config table and checked, every
// error one line naming the file and the key; a batch's spec made from its command and logs; log patterns expanded;
// the module settings every point can produce checked against the modules' tables. Thread-safety: pure functions.
#pragma once

#include <string>
#include <vector>

#include "batch/plan.h"
#include "core/result.h"

namespace driftlab::batch {

/// Reads and checks a sweep spec. Every error is one line naming the spec file and the key ("spec.yaml: vary:
/// faults.IMU.clock_ofset_s: unknown key ..."): an unknown parameter or setting, an empty grid, a value of the
/// wrong type or out of range. Module settings are checked by validate_module_settings.
Result<Spec> load_spec(const std::string& path);
/// The keys of a sweep spec, from the table load_spec reads it with (`driftlab sweep --help-config`).
std::string spec_reference();

/// A batch over logs: one point per log (paths made absolute; the same log twice is one point). stage: diagnose,
/// eval or report. Errors name the log.
Result<Spec> batch_spec(const std::string& command, const std::vector<std::string>& logs);

/// Whether a log argument is a pattern (*, ?, [...]); expand_pattern lists the regular files its last component
/// matches (fnmatch, no hidden files), sorted; the folders before it are taken as they are.
bool is_pattern(const std::string& s);
std::vector<std::string> expand_pattern(const std::string& pattern);

/// Checks the module settings every point can produce against the modules' tables (modules/settings.h), with as
/// few configs as cover every value of every varied module key. Errors name the spec file and the key.
Status validate_module_settings(const Spec& spec);

}  // namespace driftlab::batch
