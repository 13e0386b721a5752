// s2, constraint formulation: every joint and contact point of the step as rows of J̌ with their
// biases, in solve order (joints first, then contacts), grouped into solve units.
#pragma once

#include "physics/collision/manifold.h"
#include "physics/constraints/contact.h"
#include "physics/constraints/row.h"
#include "physics/model.h"
#include "physics/settings.h"

#include <vector>

namespace substep {

class ConstraintSet {
 public:
  struct JointRef {
    int joint = 0;    // index in Model::joints
    int first = 0;    // its first row
    int count = 0;    // its rows this step (limits and motors may add or drop rows)
  };

  // What a sub-step re-formulation recomputes.
  enum class Refresh {
    All,             // A3 (proc3:15): J̌ and β of every constraint from the stepped coordinates
    JointJacobians,  // A4/A5 (IV.3.2): J̌ of the joints; biases follow the update rule; contacts held
    Joints,          // the soft step: J̌ and β of the joints from the coordinates; contacts held
  };

  // Formulates everything at `poses` for time step h (the sub-step h/n under A3-A5). The rows'
  // M̌⁻¹J̌ᵀ are scaled by applyScale (κ under A5, else 1). Impulses start at zero, or at last
  // step's when warm starting.
  void build(const Model& model, const std::vector<Manifold>& manifolds, const std::vector<Pose>& poses,
             const std::vector<BodyMass>& mass, const SolverSettings& settings, double h, double applyScale);
  void reformulate(const std::vector<Pose>& poses, const std::vector<BodyMass>& mass, double h, Refresh what,
                   double applyScale);
  // Recomputes M̌⁻¹J̌ᵀ, the effective masses and the blocks of the joint rows after their J̌
  // changed (A5's stable-row prediction).
  void refinishJoints(const std::vector<BodyMass>& mass, double applyScale) { finish(0, contactFirstRow, mass, applyScale); }
  // Keeps this step's impulses: in the manifolds (for warm starting and overlays) and per joint.
  void storeImpulses(std::vector<Manifold>& manifolds);
  // Records each contact's normal velocity J̌v̌ at the step's start, for restitution.
  void recordApproach(const Vec3* v, const Vec3* w);

  std::vector<Row> rows;
  std::vector<SolveUnit> units;
  std::vector<BlockData> blocks;  // of the stable and contact blocks
  std::vector<FrictionCoupling> couplings;  // of the Friction units (their SolveUnit::block)
  std::vector<ContactDef> contacts;    // one normal row per contact point
  std::vector<FrictionDef> frictions;  // three friction rows per manifold
  std::vector<JointRef> joints;
  int contactFirstRow = 0;             // rows from here on are contacts and friction

  // Largest penetration of any contact point and largest joint error at `poses` [m].
  double maxPenetration(const std::vector<Pose>& poses) const;
  double maxJointError(const std::vector<Pose>& poses) const;

 private:
  void formulateJoint(const JointRef& ref, const std::vector<Pose>& poses, double h, bool jacobianOnly);
  void finish(int firstRow, int lastRow, const std::vector<BodyMass>& mass, double applyScale);

  const Model* model_ = nullptr;
  double slop_ = 0;
  bool stableBlocks_ = false, contactBlocks_ = false, speculative_ = true, motorUnscaled_ = true;
  std::vector<double> jointLambda_;  // per joint row, last step's impulses
  std::vector<int> jointLambdaFirst_;
  std::vector<Frame> frames_;  // the poses contacts are formulated at, as rotation matrices
};

}  // namespace substep
