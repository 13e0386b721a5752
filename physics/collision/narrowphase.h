// s1, narrowphase: FCL finds whether two shapes touch, with the normal and the depth (or, for
// shapes apart by less than a margin, their distance and nearest points); the contact points
// come from clipping the two shapes' supporting features against each other, so that a box on a
// box, a lying capsule or a cylinder on its side get their whole support from one query (FCL
// gives one point for every pair but box-box). See docs/collision.md.
#pragma once

#include "physics/collision/shape_geometry.h"
#include "physics/math.h"
#include "physics/model.h"

#include <fcl/narrowphase/collision_request.h>
#include <fcl/narrowphase/collision_result.h>
#include <fcl/narrowphase/distance_request.h>
#include <fcl/narrowphase/distance_result.h>

namespace substep {

struct ContactPoint {
  Vec3 pA = Vec3::Zero();  // point on A's surface, world [m]
  Vec3 pB = Vec3::Zero();  // point on B's surface, world [m]
  Vec3 n = Vec3::UnitY();  // unit normal from B to A: the report's p_b·n <= p_a·n + hi
  double depth = 0;        // (pB - pA)·n: penetration > 0; speculative points have depth < 0 [m]
};

constexpr int kMaxPatchPoints = 16;
struct ContactPatch {
  ContactPoint p[kMaxPatchPoints];
  int count = 0;
  void add(const ContactPoint& c) {
    if (count < kMaxPatchPoints) p[count++] = c;
  }
};

// Per-thread scratch for FCL so that a query does not allocate once warmed up.
class Narrowphase {
 public:
  Narrowphase();
  // Contact points between A and B, penetrating ones and speculative ones separated by at most
  // `margin` [m]. B may be a plane or a static triangle mesh; A may not.
  void collide(const Shape& shapeA, const CollisionShape& cA, const Pose& poseA, const Shape& shapeB,
               const CollisionShape& cB, const Pose& poseB, double margin, ContactPatch& out);
  // Overlapping boxes, and spheres and capsules against boxes, get their normal and depth in
  // closed form (separating axes, closest points), and two box faces are clipped in the
  // reference box's frame; with this set, the normal and depth from FCL as for every other pair
  // and the faces by the general clipping: the general path the closed forms are tested against.
  void useGeneralPath(bool on) { generalPath_ = on; }

 private:
  bool generalPath_ = false;
  fcl::CollisionRequestd request_;
  fcl::CollisionResultd result_;
  fcl::DistanceRequestd distanceRequest_;
  fcl::DistanceResultd distanceResult_;
};

// Two boxes by their 15 separating axes, exposed for tests: the largest gap along them [m] (apart:
// a lower bound on the distance; overlapping: minus the exact penetration depth) and its axis,
// from B towards A.
double boxBoxGap(const Vec3& hA, const Pose& A, const Vec3& hB, const Pose& B, Vec3& axis);

// Two boxes' faces along the unit normal n (from B to A) clipped against each other in the
// reference box's frame, exposed for tests: the overlap's corners within `margin` (unreduced), as
// clipFeatures gives them from the faces' world corners; false where the side of either box
// along n is an edge or a corner.
bool boxFacesClipped(const Vec3& hA, const Pose& A, const Vec3& hB, const Pose& B, const Vec3& n, double margin,
                     ContactPatch& out);

// A sphere or capsule against a box in closed form, exposed for tests: false if they are further
// apart than `margin`, else the unit normal n from the box towards the round shape, the gap
// along it (the distance when apart, minus the penetration depth when overlapping [m]) and a point
// on the box. The core segment against the box: its closest points when the core is outside the
// box, else the axis of least overlap among the box's face normals and the crossings of the
// segment with the box's edges, the radius added.
bool roundBoxContact(const Shape& round, const Pose& poseR, const Shape& box, const Pose& poseBox, double margin,
                     Vec3& n, double& gap, Vec3& onBox);

// Reduces a patch to at most four points that keep its area: the deepest, the one furthest from
// it, then the two that enlarge the enclosed area most.
void reducePatch(ContactPatch& patch, int maxPoints = 4);

// Clipping, exposed for tests: points of the incident feature that lie over the reference
// feature and within `margin` of it, with the reference on body B when refIsB. `n` points from
// B to A.
void clipFeatures(const Feature& ref, const Feature& inc, bool refIsB, const Vec3& n, double margin,
                  ContactPatch& out);

}  // namespace substep
