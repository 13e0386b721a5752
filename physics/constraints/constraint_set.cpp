#include "physics/constraints/constraint_set.h"

#include "physics/constraints/ball.h"

#include <Eigen/LU>
#include <algorithm>
#include <stdexcept>

namespace substep {

namespace {

int rowCount(const Joint& j) {
  switch (j.type) {
    case JointType::Ball: return 3;
    default: break;
  }
  throw std::invalid_argument(std::string("joint type ") + jointTypeName(j.type) + " is not supported yet");
}

}  // namespace

void ConstraintSet::build(const Model& model, const std::vector<Manifold>& manifolds, const std::vector<Pose>& poses,
                          const std::vector<BodyMass>& mass, const SolverSettings& settings, double h,
                          double applyScale) {
  model_ = &model;
  slop_ = settings.slop;
  block_ = settings.blockSolve;
  rows.clear();
  units.clear();
  contacts.clear();
  joints.clear();

  if (jointLambdaFirst_.size() != model.joints.size()) {
    jointLambdaFirst_.clear();
    int total = 0;
    for (const Joint& j : model.joints) {
      jointLambdaFirst_.push_back(total);
      total += rowCount(j);
    }
    jointLambda_.assign(static_cast<size_t>(total), 0.0);
  }

  for (size_t k = 0; k < model.joints.size(); ++k) {
    JointRef ref;
    ref.joint = static_cast<int>(k);
    ref.first = static_cast<int>(rows.size());
    ref.count = rowCount(model.joints[k]);
    rows.resize(rows.size() + static_cast<size_t>(ref.count));
    formulateJoint(ref, poses, h, false);
    for (int i = 0; i < ref.count; ++i)
      rows[static_cast<size_t>(ref.first + i)].lambda =
          settings.warmStart ? jointLambda_[static_cast<size_t>(jointLambdaFirst_[k] + i)] : 0.0;
    joints.push_back(ref);
    // Unbounded rows form one block when block solving, else one unit each.
    if (block_) {
      units.push_back(SolveUnit{ref.first, ref.count, Mat3::Zero()});
    } else {
      for (int i = 0; i < ref.count; ++i) units.push_back(SolveUnit{ref.first + i, 1, Mat3::Zero()});
    }
  }

  contactFirstRow = static_cast<int>(rows.size());
  for (const Manifold& m : manifolds) {
    for (int k = 0; k < m.count; ++k) {
      const ManifoldPoint& p = m.points[k];
      ContactDef c;
      c.a = m.a;
      c.b = m.b;
      c.localA = p.localA;
      c.localB = p.localB;
      c.localN = p.localN;
      c.mu = m.friction;
      c.restitution = m.restitution;
      contacts.push_back(c);
      const int first = static_cast<int>(rows.size());
      rows.resize(rows.size() + 3);
      formulateContact(c, poses[static_cast<size_t>(c.a)], poses[static_cast<size_t>(c.b)], h, slop_, &rows[static_cast<size_t>(first)], false);
      for (int i = 0; i < 3; ++i) rows[static_cast<size_t>(first + i)].lambda = settings.warmStart ? p.lambda[i] : 0.0;
      rows[static_cast<size_t>(first + 1)].normalRow = first;
      rows[static_cast<size_t>(first + 2)].normalRow = first;
    }
  }
  // Solve order: joints, then every contact's normal row, then the friction rows. With friction
  // interleaved, Gauss-Seidel spends its sweeps on friction impulses that fight each other under
  // a box (four points, eight tangent rows, six degrees of freedom) and a 5-box stack under A2
  // at 10 iterations falls over; normals first hold it (tests/test_stacking.cpp).
  const int nContacts = static_cast<int>(contacts.size());
  for (int k = 0; k < nContacts; ++k) units.push_back(SolveUnit{contactFirstRow + 3 * k, 1, Mat3::Zero()});
  for (int k = 0; k < nContacts; ++k)
    for (int i = 1; i < 3; ++i) units.push_back(SolveUnit{contactFirstRow + 3 * k + i, 1, Mat3::Zero()});
  finish(0, static_cast<int>(rows.size()), mass, applyScale);
}

void ConstraintSet::formulateJoint(const JointRef& ref, const std::vector<Pose>& poses, double h, bool jacobianOnly) {
  const Joint& j = model_->joints[static_cast<size_t>(ref.joint)];
  const Pose& A = poses[static_cast<size_t>(j.bodyA)];
  const Pose& B = poses[static_cast<size_t>(j.bodyB)];
  Row* r = &rows[static_cast<size_t>(ref.first)];
  switch (j.type) {
    case JointType::Ball: formulateBall(j, A, B, h, r, jacobianOnly); break;
    default: throw std::invalid_argument("unsupported joint type");
  }
}

void ConstraintSet::finish(int firstRow, int lastRow, const std::vector<BodyMass>& mass, double applyScale) {
  for (int i = firstRow; i < lastRow; ++i) {
    Row& r = rows[static_cast<size_t>(i)];
    finishRow(r, mass[static_cast<size_t>(r.a)], mass[static_cast<size_t>(r.b)], applyScale);
  }
  for (SolveUnit& u : units) {
    if (u.size == 1 || u.first < firstRow || u.first >= lastRow) continue;
    // K = block of Γ = J̌ M̌⁻¹ J̌ᵀ (unscaled, as the effective mass of single rows).
    Mat3 K = Mat3::Identity();
    for (int i = 0; i < u.size; ++i)
      for (int k = 0; k < u.size; ++k)
        K(i, k) = gammaEntry(rows[static_cast<size_t>(u.first + i)], rows[static_cast<size_t>(u.first + k)], mass.data());
    Mat3 inv = Mat3::Zero();
    if (u.size == 3) {
      bool ok = false;
      double det = 0;
      K.computeInverseAndDetWithCheck(inv, det, ok, 1e-300);
      if (!ok) inv.setZero();
    } else {
      const Eigen::Matrix2d K2 = K.topLeftCorner<2, 2>();
      const double det = K2.determinant();
      if (det != 0) inv.topLeftCorner<2, 2>() = K2.inverse();
    }
    u.invK = inv;
  }
}

void ConstraintSet::reformulate(const std::vector<Pose>& poses, const std::vector<BodyMass>& mass, double h,
                                Refresh what, double applyScale) {
  const bool jacobianOnly = what == Refresh::JointJacobians;
  for (const JointRef& ref : joints) formulateJoint(ref, poses, h, jacobianOnly);
  if (what == Refresh::All) {
    for (size_t k = 0; k < contacts.size(); ++k) {
      const ContactDef& c = contacts[k];
      formulateContact(c, poses[static_cast<size_t>(c.a)], poses[static_cast<size_t>(c.b)], h, slop_,
                       &rows[static_cast<size_t>(contactFirstRow) + 3 * k], false);
    }
    finish(0, static_cast<int>(rows.size()), mass, applyScale);
  } else {
    finish(0, contactFirstRow, mass, applyScale);
  }
}

void ConstraintSet::storeImpulses(std::vector<Manifold>& manifolds) {
  for (const JointRef& ref : joints)
    for (int i = 0; i < ref.count; ++i)
      jointLambda_[static_cast<size_t>(jointLambdaFirst_[static_cast<size_t>(ref.joint)] + i)] =
          rows[static_cast<size_t>(ref.first + i)].lambda;
  size_t k = static_cast<size_t>(contactFirstRow);
  for (Manifold& m : manifolds)
    for (int p = 0; p < m.count; ++p)
      for (int i = 0; i < 3; ++i) m.points[p].lambda[i] = rows[k++].lambda;
}

double ConstraintSet::maxPenetration(const std::vector<Pose>& poses) const {
  double worst = 0;
  for (const ContactDef& c : contacts)
    worst = std::max(worst, -contactGap(c, poses[static_cast<size_t>(c.a)], poses[static_cast<size_t>(c.b)]));
  return worst;
}

double ConstraintSet::maxJointError(const std::vector<Pose>& poses) const {
  double worst = 0;
  if (!model_) return 0;
  for (const JointRef& ref : joints) {
    const Joint& j = model_->joints[static_cast<size_t>(ref.joint)];
    const Pose& A = poses[static_cast<size_t>(j.bodyA)];
    const Pose& B = poses[static_cast<size_t>(j.bodyB)];
    worst = std::max(worst, ballError(j, A, B).norm());
  }
  return worst;
}

}  // namespace substep
