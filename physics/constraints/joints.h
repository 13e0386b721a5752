// Every joint kind as rows of J̌, through one dispatch. Each kind lives in its own file
// (ball.cpp, hinge.cpp, cone_twist.cpp, fixed.cpp, spring.cpp, motor.cpp) with its derivation.
#pragma once

#include "physics/constraints/row.h"
#include "physics/model.h"

#include <algorithm>

namespace substep {

// A joint's rows in groups. A 'stable' part has unbounded rows and is block-solved as one small
// system when block solving is on (the report's IV.2.2 item 2); other parts (limits, motors)
// are single bounded rows.
struct JointPart {
  int offset = 0;  // first row, from the joint's first
  int size = 0;    // rows: 1 to 3
  bool stable = false;
};

struct JointLayout {
  int rows = 0;
  int parts = 0;
  JointPart part[5];
  void add(int size, bool stable) {
    part[parts++] = JointPart{rows, size, stable};
    rows += size;
  }
};

JointLayout jointLayout(const Joint& j);

// Fills the joint's rows at poses A, B for time step h. jacobianOnly keeps the biases (A4/A5
// update them by the report's rule, proc4:16).
void formulateJoint(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly);

// How far the joint is from holding [m]: the separation of its anchors (a spring: its length
// error; a motor: 0).
double jointError(const Joint& j, const Pose& A, const Pose& B);

// How far a joint's angular part is from holding [rad]: a hinge's axes apart, a fixed joint's
// relative turn from its initial one; 0 for kinds that hold no angle (ball, spring, motor) and for
// cone-twists (their angles are limits, measured by jointLimitExcess).
double jointAngularError(const Joint& j, const Pose& A, const Pose& B);

// How far a joint's angles are beyond its limits [rad], by kind of limit; 0 within them.
struct LimitExcess {
  double hinge = 0;  // hinge angle beyond [lower, upper]
  double swing = 0;  // cone-twist: swing beyond the cone's half angle
  double twist = 0;  // cone-twist: twist beyond [lower, upper]
  double max() const { return std::max({hinge, swing, twist}); }
};
LimitExcess jointLimitExcess(const Joint& j, const Pose& A, const Pose& B);

// Per-kind formulations (same contract as formulateJoint).
void formulateBall(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly);
void formulateHinge(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly);
void formulateConeTwist(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly);
void formulateFixed(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly);
void formulateSpring(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly);
void formulateMotor(const Joint& j, const Pose& A, const Pose& B, double h, Row* rows, bool jacobianOnly);

// Angles the joints measure, for tests and overlays [rad].
double hingeAngle(const Joint& j, const Pose& A, const Pose& B);      // B about the axis, from A's reference
double swingAngle(const Joint& j, const Pose& A, const Pose& B);      // between the two twist axes
double twistAngle(const Joint& j, const Pose& A, const Pose& B);      // about the mean twist axis
// A fixed joint: the rotation vector that brings B's frame back onto A's (zero when it holds).
Vec3 fixedJointTurn(const Joint& j, const Pose& A, const Pose& B);

}  // namespace substep
