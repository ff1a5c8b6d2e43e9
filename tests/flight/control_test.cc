// PX4's cascade closed on a rigid-body quadrotor integrated here (thrust and drag torque per rotor, first-order
// motor lag, linear drag, a steady wind force, ground contact): it takes off to 2 m, holds there within 0.1 m
// against the wind (the velocity integrator's job) and tracks a moving setpoint along a 4 m leg within 0.3 m RMS,
// the figures. The body is simulated from its own state, not from the controller's output, and the
// controllers see its true state (the estimator is tested on its own).
#include "flight/control.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <string>

#include "flight/vehicle.h"
#include "tests/doc_figures.h"
#include "tests/flight/rigid_body.h"

namespace driftlab::flight {
namespace {

class Flight {
 public:
  Flight()
      : body_(model_, Eigen::Vector3d(0.6, -0.3, 0)),
        mixer_(model_),
        position_(o_, 4 * model_.max_rotor_thrust / model_.mass),
        attitude_(o_),
        rate_(o_) {}

  /// Flies `seconds` towards the setpoint (position, feed-forward velocity) given by `sp(t)`; `each(t)` after
  /// every millisecond of physics.
  template <class Setpoint, class Each>
  void fly(double seconds, Setpoint sp, Each each) {
    const int steps = static_cast<int>(std::lround(seconds * 1000));
    for (int i = 0; i < steps; ++i, ++tick_) {
      const double t = tick_ * 1e-3;
      if (tick_ % 20 == 0) {  // position at 50 Hz
        Eigen::Vector3d p_sp, v_ff;
        sp(t, p_sp, v_ff);
        thrust_ = position_.update(p_sp, v_ff, 0, body_.p, body_.v, 0.02);
      }
      if (tick_ % 4 == 0) {  // attitude and rates at 250 Hz
        const Eigen::Quaterniond q_sp = attitude_for(thrust_.acceleration, thrust_.yaw);
        const Eigen::Vector3d rate_sp = attitude_.update(body_.q, q_sp);
        const Eigen::Vector3d alpha = rate_.update(rate_sp, body_.w, 0.004, saturated_);
        const double collective =
            std::max(0.0, thrust_.acceleration.dot(body_.q * Eigen::Vector3d::UnitZ())) * model_.mass;
        const Mix m = mixer_.mix(collective, model_.inertia.cwiseProduct(alpha));
        for (int k = 0; k < 3; ++k) saturated_[k] = m.saturated[k];
        body_.command(m.control);
      }
      body_.step(1e-3);
      each(t + 1e-3);
    }
  }
  const test::RigidBody& body() const { return body_; }

 private:
  VehicleModel model_;
  test::RigidBody body_;
  ControlOptions o_;
  Mixer mixer_;
  PositionControl position_;
  AttitudeControl attitude_;
  RateControl rate_;
  ThrustSetpoint thrust_;
  int saturated_[3] = {0, 0, 0};
  int64_t tick_ = 0;
};

TEST(Cascade, TakesOffHoldsAgainstWindAndTracksALeg) {
  Flight f;
  // Climb at 1 m/s to 2 m, as the offboard script's setpoint does, then hold.
  auto climb = [](double t, Eigen::Vector3d& p, Eigen::Vector3d& v) {
    p = Eigen::Vector3d(0, 0, std::min(2.0, t));
    v = Eigen::Vector3d(0, 0, t < 2 ? 1.0 : 0.0);
  };
  double top = 0;
  f.fly(12, climb, [&](double) { top = std::max(top, f.body().p.z()); });
  EXPECT_LT(top, 2.3);  // a small overshoot at most
  double worst = 0;
  f.fly(5, climb, [&](double) { worst = std::max(worst, (f.body().p - Eigen::Vector3d(0, 0, 2)).norm()); });
  RecordProperty("hover_worst_m", std::to_string(worst));
  EXPECT_LT(worst, 0.1);

  // A 4 m leg east at 1 m/s with its feed-forward velocity, then 3 s at its end.
  const double start = 17;
  auto leg = [&](double t, Eigen::Vector3d& p, Eigen::Vector3d& v) {
    const double s = std::clamp(t - start, 0.0, 4.0);
    p = Eigen::Vector3d(s, 0, 2);
    v = Eigen::Vector3d(t - start < 4 ? 1.0 : 0.0, 0, 0);
  };
  double sum = 0;
  int n = 0;
  f.fly(7, leg, [&](double t) {
    Eigen::Vector3d p, v;
    leg(t, p, v);
    sum += (f.body().p - p).squaredNorm();
    ++n;
  });
  RecordProperty("leg_rms_m", std::to_string(std::sqrt(sum / n)));
  driftlab::test::expect_doc_text_figures("docs/flight.md", "the cascade held the hover within ",
                                          " m RMS; the modules'", {worst, std::sqrt(sum / n)});
  EXPECT_LT(std::sqrt(sum / n), 0.3);
  EXPECT_LT((f.body().p - Eigen::Vector3d(4, 0, 2)).norm(), 0.1);
  EXPECT_LT(Eigen::AngleAxisd(f.body().q).angle(), 0.2);  // level, but for the tilt into the wind
}

TEST(Cascade, AttitudeForPointsTheBodyAlongTheThrust) {
  const Eigen::Vector3d a(2, -1, 9.81);
  const Eigen::Quaterniond q = attitude_for(a, 0.7);
  EXPECT_LT(((q * Eigen::Vector3d::UnitZ()) - a.normalized()).norm(), 1e-9);
  // The heading of the body x axis, projected on the ground, is the yaw asked for.
  const Eigen::Vector3d x = q * Eigen::Vector3d::UnitX();
  EXPECT_NEAR(std::atan2(x.y(), x.x()), 0.7, 1e-9);
}

TEST(RateControl, StopsIntegratingIntoASaturatedAxis) {
  ControlOptions o;
  RateControl free_run(o), held(o);
  const int none[3] = {0, 0, 0}, roll_high[3] = {1, 0, 0};
  Eigen::Vector3d a, b;
  for (int i = 0; i < 250; ++i) {
    a = free_run.update(Eigen::Vector3d(1, 0, 0), Eigen::Vector3d::Zero(), 0.004, none);
    b = held.update(Eigen::Vector3d(1, 0, 0), Eigen::Vector3d::Zero(), 0.004, roll_high);
  }
  EXPECT_NEAR(b.x(), o.rate_p_rp, 1e-9);  // P alone: the integrator never moved
  EXPECT_GT(a.x(), b.x() + 5);            // 1 s of I at 12 per second, up to the limit of 8
}

}  // namespace
}  // namespace driftlab::flight
