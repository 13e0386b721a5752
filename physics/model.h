// The immutable description of a simulation: bodies, shapes, joints, gravity.
// Mutable quantities (coordinates, velocities, time) live in State (state.h), as MuJoCo separates
// mjModel from mjData: steppers take `const Model&` and change only the State.
#pragma once

#include "physics/math.h"

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace substep {

enum class ShapeType { Sphere, Box, Capsule, Cylinder, ConvexMesh, Plane, TriangleMesh };
const char* shapeTypeName(ShapeType t);

// Triangle mesh, vertices in the body frame (centre of mass, principal axes) for convex meshes,
// in the body frame of a static body for triangle meshes.
struct Mesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<int, 3>> triangles;
  std::string file;  // the asset it was loaded from, for messages
};

// Capsules and cylinders have their axis along the local Y axis (Y is up), radius around it.
struct Shape {
  ShapeType type = ShapeType::Box;
  double radius = 0;                  // sphere, capsule, cylinder [m]
  double halfHeight = 0;              // capsule, cylinder: half the length of the axis segment [m]
  Vec3 halfExtents = Vec3::Zero();    // box [m]
  Vec3 normal = Vec3::UnitY();        // plane: points out of the solid half-space
  double offset = 0;                  // plane: n . x = offset on the surface [m]
  std::shared_ptr<const Mesh> mesh;   // convex and triangle meshes
  double scale = 1;                   // meshes: uniform scale already applied to `mesh`

  // Largest distance of the shape's surface from the body origin [m] (planes: 0).
  double boundingRadius() const;
};

struct Body {
  std::string name;
  Shape shape;
  bool isStatic = false;
  double mass = 0;                    // [kg], 0 for static bodies
  double invMass = 0;                 // [1/kg]
  Vec3 inertia = Vec3::Zero();        // principal moments I1, I2, I3 [kg m^2]
  Vec3 invInertia = Vec3::Zero();     // the report's rotational M̌⁻¹ = diag(1/I1, 1/I2, 1/I3) [1/(kg m^2)]
  double friction = 0.5;              // Coulomb coefficient μ (pairs use sqrt(μa μb))
  double restitution = 0;             // e (pairs use max(ea, eb))
  int group = -1;                     // bodies made together (a ragdoll, a chain); for colouring
  // Collision filtering, as Box2D and Bullet have it: two bodies may touch when each one's
  // category has a bit in the other's mask, and they do not share a negative filter group.
  uint32_t category = 1;
  uint32_t mask = 0xFFFFFFFFu;
  int filterGroup = 0;                // < 0: never touches a body of the same group (a chain's links)
};

// Whether bodies a and b may touch (the filter; joints' "collide" is the broadphase's business).
inline bool mayTouch(const Body& a, const Body& b) {
  if (a.filterGroup < 0 && a.filterGroup == b.filterGroup) return false;
  return (a.category & b.mask) != 0 && (b.category & a.mask) != 0;
}

enum class JointType { Ball, Hinge, ConeTwist, Fixed, Spring, Motor };
const char* jointTypeName(JointType t);

// A joint between bodies a and b. Anchors and axes are stored in each body's frame; scene files
// give them in world coordinates at the initial configuration.
struct Joint {
  std::string name;
  JointType type = JointType::Ball;
  int bodyA = -1, bodyB = -1;
  Vec3 localAnchorA = Vec3::Zero(), localAnchorB = Vec3::Zero();  // [m]
  Vec3 localAxisA = Vec3::UnitX(), localAxisB = Vec3::UnitX();    // hinge axis, twist axis, motor axis
  Vec3 localRefA = Vec3::UnitY(), localRefB = Vec3::UnitY();      // perpendicular to the axis: angle zero
  bool hasLimits = false;
  double lower = 0, upper = 0;        // hinge and twist angle limits [rad]
  double swing = 0;                   // cone-twist: swing cone half angle [rad]
  bool hasMotor = false;
  double motorSpeed = 0;              // [rad/s] about the axis (hinge, motor)
  double motorMaxTorque = 0;          // [N m]; 0 means unbounded
  double restLength = 0;              // spring: distance between the anchors [m]
  bool collide = false;               // let the two bodies collide with each other
};

struct Model {
  std::string name;
  Vec3 gravity = Vec3(0, -9.81, 0);   // [m/s^2]
  std::vector<Body> bodies;
  std::vector<Joint> joints;

  int bodyIndex(const std::string& name) const;  // -1 if absent
  int dynamicCount() const;
};

}  // namespace substep
