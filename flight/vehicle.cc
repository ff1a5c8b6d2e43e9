#include "flight/vehicle.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <string>

#include "core/config.h"

namespace driftlab::flight {
namespace {

/// rotors: a list of [x, y, direction], at least four, direction +1 or -1.
Status read_rotors(const config::Value& v, std::vector<Rotor>& out) {
  if (!v.node().IsSequence() || v.node().size() < 4) {
    return v.error("must be a list of at least 4 rotors, each [x, y, direction]");
  }
  std::vector<Rotor> rotors;
  for (std::size_t i = 0; i < v.node().size(); ++i) {
    auto r = v[i].numbers(3, config::between(-100, 100), "m, m, 1");
    if (!r) return r.error();
    if ((*r)[2] != 1 && (*r)[2] != -1) return v[i].error("direction must be 1 (counter-clockwise) or -1 (clockwise)");
    rotors.push_back({(*r)[0], (*r)[1], static_cast<int>((*r)[2])});
  }
  out = std::move(rotors);
  return {};
}

std::string show_rotors(const std::vector<Rotor>& rotors) {
  std::string s = "[";
  for (const Rotor& r : rotors) {
    s += (s.size() > 1 ? ", [" : "[") + config::format_number(r.x) + ", " + config::format_number(r.y) + ", " +
         std::to_string(r.direction) + "]";
  }
  return s + "]";
}

}  // namespace

const config::Table<VehicleModel>& vehicle_model_table() {
  using V = VehicleModel;
  static const auto t =
      config::Table<V>()
          .number("mass", &V::mass, config::above(0, 1e4), "kg", "the vehicle's mass, as the controller believes it")
          .numbers("inertia", &V::inertia, config::above(0, 1e4), "kg*m^2",
                   "principal moments of inertia about x, y, z")
          .custom<std::vector<Rotor>>("rotors", &V::rotors, "list of [x, y, direction]", "m, m, 1", "at least 4",
                                      "where each rotor's thrust acts in the body frame (x forward, y left) and its "
                                      "spin: 1 counter-clockwise seen from above, -1 clockwise; motor order",
                                      read_rotors, show_rotors)
          .number("max_rotor_thrust", &V::max_rotor_thrust, config::above(0, 1e5), "N",
                  "thrust of one rotor at full command")
          .number("moment_ratio", &V::moment_ratio, config::between(0, 10), "m",
                  "a rotor's drag torque per unit of its thrust (k_m / k_f)")
          .check([](const config::Value& v, V& m) -> Status {
            Mixer mixer(m);  // the rotors must be able to make every torque
            const Eigen::Vector4d e =
                mixer.effect(mixer.mix(m.mass * 9.81, Eigen::Vector3d(0.01, 0.01, 0.001)).control);
            if (!(std::abs(e(1) - 0.01) < 1e-6 && std::abs(e(2) - 0.01) < 1e-6)) {
              return v["rotors"].error("cannot make roll and pitch torques (rotors in a line?)");
            }
            return {};
          });
  return t;
}

Mixer::Mixer(const VehicleModel& model) : model_(model) {
  const auto n = static_cast<Eigen::Index>(model.rotors.size());
  B_.resize(4, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Rotor& r = model.rotors[static_cast<std::size_t>(i)];
    // A thrust f at (x, y) pushes up by f and turns the body by (x, y, 0) x (0, 0, f) = (y f, -x f, 0); its drag
    // turns the body against the rotor's spin.
    B_.col(i) << 1, r.y, -r.x, -r.direction * model.moment_ratio;
  }
  const Eigen::Matrix4d BBt = B_ * B_.transpose();
  B_inv_ = B_.transpose() * BBt.completeOrthogonalDecomposition().pseudoInverse();
}

Mix Mixer::mix(double thrust, const Eigen::Vector3d& torque) const {
  const double fmax = model_.max_rotor_thrust;
  const Eigen::VectorXd u_thrust = B_inv_ * Eigen::Vector4d(thrust, 0, 0, 0) / fmax;
  Eigen::VectorXd u_rp = B_inv_ * Eigen::Vector4d(0, torque.x(), torque.y(), 0) / fmax;
  const Eigen::VectorXd u_yaw = B_inv_ * Eigen::Vector4d(0, 0, 0, torque.z()) / fmax;
  Mix out;
  // Roll and pitch first: if their spread does not fit the motors' range, scale them down.
  const double spread = u_rp.maxCoeff() - u_rp.minCoeff();
  if (spread > 1) {
    u_rp /= spread;
    out.saturated[0] = torque.x() > 0 ? 1 : (torque.x() < 0 ? -1 : 0);
    out.saturated[1] = torque.y() > 0 ? 1 : (torque.y() < 0 ? -1 : 0);
  }
  // Then the collective thrust: shifted to make room for them.
  Eigen::VectorXd u = u_thrust + u_rp;
  if (u.maxCoeff() > 1) {
    u.array() -= u.maxCoeff() - 1;
    out.thrust_limited = true;
  }
  if (u.minCoeff() < 0) {
    u.array() -= u.minCoeff();
    out.thrust_limited = true;
  }
  // Yaw last, as much of it as fits.
  double k = 1;
  for (Eigen::Index i = 0; i < u.size(); ++i) {
    if (u_yaw(i) > 0 && u(i) + u_yaw(i) > 1) k = std::min(k, std::max(0.0, (1 - u(i)) / u_yaw(i)));
    if (u_yaw(i) < 0 && u(i) + u_yaw(i) < 0) k = std::min(k, std::max(0.0, -u(i) / u_yaw(i)));
  }
  if (k < 1) out.saturated[2] = torque.z() > 0 ? 1 : -1;
  u += k * u_yaw;
  out.control.resize(static_cast<std::size_t>(u.size()));
  for (Eigen::Index i = 0; i < u.size(); ++i) out.control[static_cast<std::size_t>(i)] = std::clamp(u(i), 0.0, 1.0);
  return out;
}

Eigen::Vector4d Mixer::effect(const std::vector<double>& control) const {
  Eigen::VectorXd f(static_cast<Eigen::Index>(control.size()));
  for (std::size_t i = 0; i < control.size(); ++i)
    f(static_cast<Eigen::Index>(i)) = control[i] * model_.max_rotor_thrust;
  return B_ * f;
}

}  // namespace driftlab::flight
