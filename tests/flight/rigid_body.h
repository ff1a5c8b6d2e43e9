// A rigid-body quadrotor for the flight stack's tests, integrated from its own state: each rotor's thrust follows
// its command with a first-order lag, the mixer's effectiveness matrix turns the rotors' thrusts into the
// collective force and torques (the same physics as the rotors at (x, y) with drag torque k_m/k_f * thrust),
// linear drag, a steady wind force, gravity and a ground that holds the body up. Semi-implicit Euler at the step
// given. Units: SI; frames: local east-north-up, body x forward, y left, z up.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <utility>
#include <vector>

#include "flight/vehicle.h"

namespace driftlab::flight::test {

class RigidBody {
 public:
  explicit RigidBody(const VehicleModel& model, Eigen::Vector3d wind = Eigen::Vector3d::Zero())
      : model_(model), mixer_(model), wind_(std::move(wind)), thrust_(model.rotors.size(), 0.0), command_(thrust_) {}

  /// Motor commands, per rotor [0..1] of the maximum thrust; all zero when disarmed.
  void command(const std::vector<double>& control) { command_ = control; }
  void step(double dt) {
    const double lag = 0.03;  // [s]
    for (std::size_t k = 0; k < thrust_.size(); ++k) thrust_[k] += (command_[k] - thrust_[k]) * (dt / lag);
    const Eigen::Vector4d e = mixer_.effect(thrust_);
    const Eigen::Vector3d force = q * Eigen::Vector3d(0, 0, e(0)) - 0.25 * v + wind_;
    const Eigen::Vector3d a = force / model_.mass - Eigen::Vector3d(0, 0, 9.81);
    const Eigen::Vector3d I = model_.inertia;
    w += (e.tail<3>() - w.cross(I.cwiseProduct(w))).cwiseQuotient(I) * dt;
    const double angle = w.norm() * dt;
    if (angle > 0) q = (q * Eigen::Quaterniond(Eigen::AngleAxisd(angle, w.normalized()))).normalized();
    v += a * dt;
    p += v * dt;
    if (p.z() <= 0) {  // on the ground: held up and still
      p.z() = 0;
      v.setZero();
      w.setZero();
    }
  }

  Eigen::Vector3d p = Eigen::Vector3d::Zero(), v = Eigen::Vector3d::Zero(), w = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();

 private:
  VehicleModel model_;
  Mixer mixer_;
  Eigen::Vector3d wind_;
  std::vector<double> thrust_, command_;  // [0..1] of the maximum
};

}  // namespace driftlab::flight::test
