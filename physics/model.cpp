#include "physics/model.h"
#include "physics/state.h"

#include <algorithm>

namespace substep {

const char* shapeTypeName(ShapeType t) {
  switch (t) {
    case ShapeType::Sphere: return "sphere";
    case ShapeType::Box: return "box";
    case ShapeType::Capsule: return "capsule";
    case ShapeType::Cylinder: return "cylinder";
    case ShapeType::ConvexMesh: return "convex";
    case ShapeType::Plane: return "plane";
    case ShapeType::TriangleMesh: return "mesh";
  }
  return "?";
}

const char* jointTypeName(JointType t) {
  switch (t) {
    case JointType::Ball: return "ball";
    case JointType::Hinge: return "hinge";
    case JointType::ConeTwist: return "cone_twist";
    case JointType::Fixed: return "fixed";
    case JointType::Spring: return "spring";
    case JointType::Motor: return "motor";
  }
  return "?";
}

double Shape::boundingRadius() const {
  switch (type) {
    case ShapeType::Sphere: return radius;
    case ShapeType::Box: return halfExtents.norm();
    case ShapeType::Capsule: return halfHeight + radius;
    case ShapeType::Cylinder: return std::sqrt(halfHeight * halfHeight + radius * radius);
    case ShapeType::ConvexMesh:
    case ShapeType::TriangleMesh: {
      double r = 0;
      if (mesh)
        for (const Vec3& v : mesh->vertices) r = std::max(r, v.norm());
      return r;
    }
    case ShapeType::Plane: return 0;
  }
  return 0;
}

int Model::bodyIndex(const std::string& n) const {
  for (size_t i = 0; i < bodies.size(); ++i)
    if (bodies[i].name == n) return static_cast<int>(i);
  return -1;
}

int Model::dynamicCount() const {
  return static_cast<int>(std::count_if(bodies.begin(), bodies.end(), [](const Body& b) { return !b.isStatic; }));
}

bool State::finite() const {
  for (const BodyState& b : bodies)
    if (!allFinite(b.x) || !allFinite(b.v) || !allFinite(b.w) || !std::isfinite(b.q.w()) || !allFinite(b.q.vec()))
      return false;
  return true;
}

}  // namespace substep
