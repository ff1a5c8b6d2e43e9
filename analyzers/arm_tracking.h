// The tracking error of an arm in a log (`driftlab eval --arm LOG`): how far its joints were from where they were
// commanded, per joint, and how far its end effector was from the pose the commanded joints put it at, against
// ground truth, with the forward kinematics of the URDF the log carries (driftlab.robot_description_t).
// Thread-safety: pure function of the log.
#pragma once

#include <string>
#include <vector>

#include "analyzers/trajectory.h"
#include "core/result.h"

namespace driftlab::analyzers {

/// What the measured joints are compared with.
enum class ArmReference {
  /// The commands' plans (driftlab.joint_trajectory_t) at their stamps: at time t, the plan of the last command
  /// stamped at or before t (as `driftlab diagnose` reads the command loop). What the sender asked for, when it
  /// asked: a late transport, a controller that starts plans late and the controller's own error all count.
  kCommanded,
  /// The joint trajectory controller's desired state (driftlab.joint_trajectory_state_t, ros2_control's
  /// controller state) at its stamps: the controller's own tracking error, whatever its commands' timing.
  kDesired,
};
const char* to_string(ArmReference reference);

struct ArmTrackingOptions {
  ArmReference reference = ArmReference::kCommanded;
  /// Channels; "" finds them by type: the joint trajectory channel with the most commands, the joint state and
  /// controller state channels with all its joints (the most messages), the robot description, and two ground
  /// truth poses (driftlab.pose_t) in one frame: the end effector (the pose whose child_frame_id is the deepest
  /// link the commanded joints move) and the arm's base (the nearest link above the first commanded joint).
  std::string command_channel, ee_channel, base_channel;
  /// The oscillation: the part of the end effector's motion above this frequency [Hz] (a pick-and-place plan's
  /// minimum-jerk moves of a second or more lie below it).
  double oscillation_cutoff_hz = 5.0;
};

/// Errors of one commanded joint, and what it reached against its URDF limits.
struct JointTracking {
  std::string name;
  Stats error_rad;             ///< |measured - reference| [rad or m] at the joint states' stamps
  double mean_signed_rad = 0;  ///< mean of measured - reference: a lag shows here with the motion's sign
  bool has_position_limits = false;
  double lower = 0, upper = 0;  ///< the URDF's position limits [rad or m]
  double velocity_limit = 0;    ///< [rad/s or m/s]; 0: none in the URDF
  double min = 0, max = 0;      ///< positions reached over the whole log
  double max_speed = 0;         ///< largest |velocity| the joint states report over the whole log
  int64_t beyond_position = 0;  ///< joint states beyond a position limit [count]
  int64_t beyond_velocity = 0;  ///< joint states faster than the velocity limit [count]
};

/// How the end effector shakes: its true motion in the base link's frame above the cutoff frequency, where a
/// planned motion has next to nothing (each axis resampled at 100 Hz, less its mean, through a Hann window, by FFT;
/// the three power spectra added): the RMS of that part, and the frequency where most of it lies. A loop that
/// re-plans on late commands shakes at its command rate.
struct Oscillation {
  double cutoff_hz = 0;
  double rms_m = 0;    ///< [m]
  double peak_hz = 0;  ///< the strongest frequency above the cutoff [Hz]
};

struct ArmTracking {
  std::string log;
  ArmReference reference = ArmReference::kCommanded;
  std::string command_channel, state_channel, controller_channel, description_channel, ee_channel, base_channel;
  std::string base_link, tip_link;  ///< the chain the end effector is computed along (empty without ground truth)
  int64_t commands = 0;
  double start_s = 0, end_s = 0;  ///< the span compared, from the log's first event [s]
  std::vector<JointTracking> joints;
  /// End effector: |FK(reference joints) - true pose| in the base link's frame, at the ground truth's stamps;
  /// count 0 without ground truth (`ee_problem` says why).
  Stats ee_position_m, ee_rotation_deg;
  Oscillation oscillation;
  std::string ee_problem;
  /// The error over time, for plots: times [s from the log's first event], position error [m], angle [deg].
  std::vector<double> ee_t, ee_position_error, ee_rotation_error;
};

/// Errors name the log and what is missing (no commands, no joint states with their joints, no URDF, a URDF
/// that does not parse, a channel that is not there or not of its type).
Result<ArmTracking> evaluate_arm(const std::string& log, const ArmTrackingOptions& options = {});

}  // namespace driftlab::analyzers
