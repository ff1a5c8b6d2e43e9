#include "sim/arm_config.h"

#include "core/config.h"

namespace driftlab::sim {

const config::Table<ArmConfig>& arm_table() {
  using A = ArmConfig;
  using config::Text;
  static const auto t =
      config::Table<A>()
          .text("command_channel", &A::command_channel, "driftlab.joint_trajectory_t from the commander",
                Text::kNonEmpty)
          .text("state_channel", &A::state_channel, "driftlab.joint_trajectory_state_t of the controller",
                Text::kNonEmpty)
          .text("result_channel", &A::result_channel, "driftlab.joint_trajectory_result_t of the controller",
                Text::kNonEmpty)
          .text("description_channel", &A::description_channel, "driftlab.robot_description_t, once at the start",
                Text::kNonEmpty)
          .text("joints_tf_channel", &A::joints_tf_channel,
                "driftlab.tf_t of every moving joint (the robot state publisher)", Text::kNonEmpty)
          .number("joints_tf_rate", &A::joints_tf_rate, config::above(0, 1000), "Hz",
                  "how often the robot state publisher publishes")
          .text("map_channel", &A::map_channel, "driftlab.tf_t of map -> odom from the localization; \"\" for none")
          .number("map_rate", &A::map_rate, config::above(0, 1000), "Hz", "how often the localization publishes")
          .flag("hold_base", &A::hold_base, "the base holds still instead of driving the route")
          .section("controller", &A::controller, controller::joint_trajectory_table(),
                   "the joint trajectory controller, updated every physics step")
          .section("commander", &A::commander, controller::arm_commander_table(),
                   "the commander: the pick-and-place cycle, sent over the command channel");
  return t;
}

}  // namespace driftlab::sim
