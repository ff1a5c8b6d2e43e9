// What the flight stack knows of its multirotor (PX4's airframe parameters: CA_ROTORn_PX/PY/KM, the hover thrust),
// and its control allocation: the mixer that turns a collective thrust and body torques into motor commands.
// Frames: body x forward, y left, z up; a rotor spinning counter-clockwise seen from above (+z) pushes the body
// clockwise with its drag. Units: SI. Thread-safety: plain values; the functions are reentrant.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "core/result.h"

namespace driftlab::config {
template <class T>
class Table;
class Value;
}  // namespace driftlab::config

namespace driftlab::flight {

struct Rotor {
  double x = 0, y = 0;  ///< where its thrust acts, in the body frame [m]
  int direction = 1;    ///< +1: spins counter-clockwise seen from above; -1: clockwise
};

struct VehicleModel {
  double mass = 1.2;                                                  ///< [kg]
  Eigen::Vector3d inertia = Eigen::Vector3d(0.0118, 0.0118, 0.0205);  ///< principal moments about x, y, z [kg*m^2]
  /// The shipped quadrotor (sim/robots/quadrotor.urdf): X layout, 0.25 m arms, front-right and back-left
  /// counter-clockwise.
  std::vector<Rotor> rotors = {
      {0.1768, -0.1768, 1}, {-0.1768, 0.1768, 1}, {0.1768, 0.1768, -1}, {-0.1768, -0.1768, -1}};
  double max_rotor_thrust = 7.07;  ///< thrust of one rotor at full command [N]
  double moment_ratio = 0.06;      ///< drag torque per unit thrust of a rotor (k_m / k_f) [m]
};

/// The keys of a vehicle model (mass, inertia, rotors, max_rotor_thrust, moment_ratio), core/config.h.
const config::Table<VehicleModel>& vehicle_model_table();

/// What the mixer made of a demand.
struct Mix {
  std::vector<double> control;  ///< per rotor, normalised thrust [0..1]
  /// Per torque axis (x, y, z): the demand could not be met fully, +1 above, -1 below (for the rate controller's
  /// anti-windup); 0: met.
  int saturated[3] = {0, 0, 0};
  bool thrust_limited = false;  ///< the collective thrust was changed to make room for the torques
};

/// Control allocation by the pseudo-inverse of the rotors' effectiveness, with PX4's priorities when a motor
/// saturates: roll and pitch torque first, then collective thrust, then yaw.
class Mixer {
 public:
  explicit Mixer(const VehicleModel& model);
  /// thrust: collective [N]; torque: about the body axes [N*m].
  Mix mix(double thrust, const Eigen::Vector3d& torque) const;
  /// The collective thrust and torques that motor commands produce (for tests and the simulator's checks).
  Eigen::Vector4d effect(const std::vector<double>& control) const;

 private:
  VehicleModel model_;
  Eigen::Matrix<double, 4, Eigen::Dynamic> B_;      ///< rotor thrusts [N] -> thrust [N], torque [N*m]
  Eigen::Matrix<double, Eigen::Dynamic, 4> B_inv_;  ///< its pseudo-inverse
};

}  // namespace driftlab::flight
