// Fault descriptions embedded in another YAML document (a simulator scenario's `faults:` key): parsing the node
// keeps line numbers pointing into the enclosing file.
#pragma once

#include <yaml-cpp/yaml.h>

#include <string>

#include "core/faults.h"

namespace driftlab {

Result<FaultConfig> parse_faults(const YAML::Node& root, const std::string& origin);

}  // namespace driftlab
