#include "physics/constraints/joints.h"

#include "physics/constraints/ball.h"

#include <algorithm>
#include <cmath>

namespace substep {

JointLayout jointLayout(const Joint& j) {
  JointLayout l;
  switch (j.type) {
    case JointType::Ball: l.add(3, true); break;
    case JointType::Hinge:
      l.add(3, true);  // anchors
      l.add(2, true);  // axes aligned
      if (j.hasLimits) {
        l.add(1, false);  // lower angle
        l.add(1, false);  // upper angle
      }
      if (j.hasMotor) l.add(1, false);
      break;
    case JointType::ConeTwist:
      l.add(3, true);   // anchors
      l.add(1, false);  // swing cone
      if (j.hasLimits) {
        l.add(1, false);  // lower twist
        l.add(1, false);  // upper twist
      }
      break;
    case JointType::Fixed:
      l.add(3, true);
      l.add(3, true);
      break;
    case JointType::Spring: l.add(1, true); break;
    case JointType::Motor: l.add(1, false); break;
  }
  return l;
}

void formulateJoint(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly) {
  switch (j.type) {
    case JointType::Ball: formulateBall(j, A, B, h, rows, jacobianOnly); break;
    case JointType::Hinge: formulateHinge(j, A, B, h, rows, jacobianOnly); break;
    case JointType::ConeTwist: formulateConeTwist(j, A, B, h, rows, jacobianOnly); break;
    case JointType::Fixed: formulateFixed(j, A, B, h, rows, jacobianOnly); break;
    case JointType::Spring: formulateSpring(j, A, B, h, rows, jacobianOnly); break;
    case JointType::Motor: formulateMotor(j, A, B, h, rows, jacobianOnly); break;
  }
}

double jointError(const Joint& j, const Pose& A, const Pose& B) {
  switch (j.type) {
    case JointType::Spring:
      return std::abs((A.apply(j.localAnchorA) - B.apply(j.localAnchorB)).norm() - j.restLength);
    case JointType::Motor: return 0;
    default: return ballError(j, A, B).norm();
  }
}

double jointAngularError(const Joint& j, const Pose& A, const Pose& B) {
  switch (j.type) {
    case JointType::Hinge: return swingAngle(j, A, B);  // the angle between the two axes, as a cone's swing
    case JointType::Fixed: return fixedJointTurn(j, A, B).norm();
    default: return 0;
  }
}

LimitExcess jointLimitExcess(const Joint& j, const Pose& A, const Pose& B) {
  LimitExcess e;
  if (j.type == JointType::Hinge && j.hasLimits) {
    const double t = hingeAngle(j, A, B);
    e.hinge = std::max({0.0, j.lower - t, t - j.upper});
  } else if (j.type == JointType::ConeTwist) {
    e.swing = std::max(0.0, swingAngle(j, A, B) - j.swing);
    if (j.hasLimits) {
      const double t = twistAngle(j, A, B);
      e.twist = std::max({0.0, j.lower - t, t - j.upper});
    }
  }
  return e;
}

}  // namespace substep
