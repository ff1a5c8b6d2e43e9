// The readers Foxglove itself runs (tests/oracle/dump.mjs: @mcap/core, @foxglove/rosbag, @foxglove/rosmsg2-
// serialization, @foxglove/rosmsg-serialization, @foxglove/cdr) as the judge of what driftlab reads and writes:
// every message they decode must equal driftlab's, field by field.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "tests/test_util.h"

namespace driftlab::test {

/// Every message of file as the oracle decodes it, in its order (MCAP: file order; ROS 1 bags: time order;
/// sqlite3: row order). When node or the npm modules are missing the calling test is skipped, except under CI
/// (CI=true), where that is a failure. Use as: `auto msgs = oracle_messages(f); if (!msgs) return;`
std::optional<std::vector<nlohmann::json>> oracle_messages(const std::string& file);

/// Writes the MCAP file out with the writers Foxglove runs (tests/oracle/write_mcap.mjs: @mcap/core,
/// @foxglove/rosmsg2-serialization or @foxglove/rosmsg-serialization) from spec: {"profile": "ros2"|"ros1",
/// "compression": "zstd"|"none", "messages": [dump lines: topic, type, time_ns, sequence, msg]}, numbers JSON cannot
/// hold as "NaN", "Infinity", "-Infinity". False (the test skipped, or failed under CI) without node.
bool oracle_write_mcap(const nlohmann::json& spec, const std::string& out);

/// Writes the MCAP file in again as out with Foxglove's writer (tests/oracle/relayout_mcap.mjs: @mcap/core's
/// McapWriter), every schema, channel, message, metadata and attachment kept, in the layout the writer's options
/// give (layout: McapWriter's options, "compression": "zstd"|"none", an "attachment" and a "metadata" record to
/// add). False (the test skipped, or failed under CI) without node.
bool oracle_relayout_mcap(const std::string& in, const std::string& out, const nlohmann::json& layout);

/// Compares a ROS message as the oracle decoded it (`ros` is one dump line: topic, type, time_ns, msg) with the
/// driftlab event driftlab made of it: the event time, header.utime from header.stamp, header.seq (`seq`), and
/// every field the mapping carries; foreign messages by walking their payload with their schema.
/// `schema` is the FOREIGN_SCHEMAS definition of the channel (foreign messages only).
void expect_same_message(const nlohmann::json& ros, const OwnedEvent& event, int64_t seq,
                         const std::string& schema = "");

}  // namespace driftlab::test
