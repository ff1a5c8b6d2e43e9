// The processing modules `driftlab replay` and `driftlab run` can host (modules/module_table.h), made from one
// YAML config (a map of module name -> settings, docs/replay.md) in one place, so both commands offer the same
// modules with the same settings and the same errors. Thread-safety: pure functions.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/result.h"
#include "modules/module_table.h"
#include "modules/settings.h"
#include "runtime/bus.h"

namespace driftlab::modules {

/// The modules named in `list` (comma-separated) with their settings from the YAML file at `config_path` (empty:
/// every module with its defaults). `notes` receives what was chosen for the user ("slam: 2d backend"). Errors
/// (an unknown module, a bad file, a bad key or value) are one line naming the file, line and key. `inputs` is
/// what the run delivers (empty live): the slam module's `auto` backend and its input channels, when not set, are
/// found there.
Result<std::vector<std::unique_ptr<Module>>> load_modules(const std::string& list, const std::string& config_path,
                                                          const InputChannels& inputs, std::vector<std::string>& notes);

}  // namespace driftlab::modules
