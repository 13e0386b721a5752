#include "render/scene_builder.h"

#include "physics/collision/shape_geometry.h"
#include "physics/constraints/joints.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>

namespace substep::render {

namespace {

constexpr double kDegree = 3.14159265358979323846 / 180.0;

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

Vec3f hsv(float h, float s, float v) {
  h = h - std::floor(h);
  const float c = v * s, x = c * (1 - std::abs(std::fmod(h * 6, 2.0f) - 1)), m = v - c;
  Vec3f rgb;
  switch (static_cast<int>(h * 6) % 6) {
    case 0: rgb = {c, x, 0}; break;
    case 1: rgb = {x, c, 0}; break;
    case 2: rgb = {0, c, x}; break;
    case 3: rgb = {0, x, c}; break;
    case 4: rgb = {x, 0, c}; break;
    default: rgb = {c, 0, x}; break;
  }
  return rgb + Vec3f::Constant(m);
}

// The largest 1, 2 or 5 times a power of ten not above x (> 0).
double niceFloor(double x) {
  const double p = std::pow(10.0, std::floor(std::log10(x)));
  const double m = x / p;
  return (m >= 5 ? 5 : m >= 2 ? 2 : 1) * p;
}

// The rotation taking +Y to the unit vector d.
Quatf fromY(const Vec3f& d) { return Quatf::FromTwoVectors(Vec3f::UnitY(), d); }

// A thin cylinder from a to b (an arm, a normal, an axis).
Instance segment(const Vec3f& a, const Vec3f& b, float radius, const Vec3f& colour) {
  Instance in;
  in.mesh = kCylinderMesh;
  const Vec3f d = b - a;
  const float len = d.norm();
  in.position = 0.5f * (a + b);
  in.rotation = len > 1e-9f ? fromY(d / len) : Quatf::Identity();
  in.scale = Vec3f(radius, 0.5f * len, radius);
  in.colour = Vec4f(colour.x(), colour.y(), colour.z(), 1.0f);
  in.flags = kNoShadow;
  return in;
}

// An arrow from a to b: a shaft of `radius` and a cone head 3.5 radii wide and 10 long, shrunk
// with the arrow when it is shorter than twice its head.
void arrow(std::vector<Instance>& out, const Vec3f& a, const Vec3f& b, float radius, const Vec3f& colour) {
  const Vec3f d = b - a;
  const float len = d.norm();
  if (!(len > 1e-9f)) return;
  const float shrink = std::min(1.0f, 0.5f * len / (10 * radius));
  const float headLen = 10 * radius * shrink, headR = 3.5f * radius * shrink;
  const Vec3f u = d / len, neck = b - headLen * u;
  if (len > headLen) out.push_back(segment(a, neck, radius * std::max(shrink, 0.5f), colour));
  Instance head;
  head.mesh = kConeMesh;
  head.position = 0.5f * (neck + b);
  head.rotation = fromY(u);
  head.scale = Vec3f(headR, 0.5f * headLen, headR);
  head.colour = Vec4f(colour.x(), colour.y(), colour.z(), 1.0f);
  head.flags = kNoShadow;
  out.push_back(head);
}

Instance dot(const Vec3f& p, float radius, const Vec3f& colour) {
  Instance in;
  in.mesh = kSphereMesh;
  in.position = p;
  in.scale = Vec3f::Constant(radius);
  in.colour = Vec4f(colour.x(), colour.y(), colour.z(), 1.0f);
  in.flags = kNoShadow;
  return in;
}

// Bounds of the bodies that cast shadows worth resolving: the dynamic ones, and static ones no
// bigger than them (a ground box 40 m wide would spread the shadow map thin).
void shadowBounds(const Model& model, const State& state, Vec3f& centre, float& radius) {
  Eigen::AlignedBox3d box;
  for (size_t i = 0; i < model.bodies.size(); ++i) {
    const Body& b = model.bodies[i];
    if (b.isStatic) continue;
    const double r = b.shape.boundingRadius();
    box.extend(state.bodies[i].x - Vec3::Constant(r));
    box.extend(state.bodies[i].x + Vec3::Constant(r));
  }
  const double dynR = box.isEmpty() ? 1.0 : 0.5 * box.diagonal().norm();
  for (size_t i = 0; i < model.bodies.size(); ++i) {
    const Body& b = model.bodies[i];
    if (!b.isStatic || b.shape.type == ShapeType::Plane) continue;
    const double r = b.shape.boundingRadius();
    if (r > 2 * dynR) continue;
    box.extend(state.bodies[i].x - Vec3::Constant(r));
    box.extend(state.bodies[i].x + Vec3::Constant(r));
  }
  if (box.isEmpty()) {
    centre = Vec3f::Zero();
    radius = 10;
    return;
  }
  centre = box.center().cast<float>();
  radius = std::max(0.5f, static_cast<float>(0.5 * box.diagonal().norm()));
}

// How far a body's surface reaches along the unit direction d (world), from the world origin.
double reach(const Shape& shape, const Pose& pose, const Vec3& d) {
  if (shape.type == ShapeType::Plane) return std::numeric_limits<double>::infinity();  // unbounded
  if (shape.type == ShapeType::TriangleMesh) return d.dot(pose.p) + shape.boundingRadius();
  const Feature f = supportingFeature(shape, pose, d);
  double best = -std::numeric_limits<double>::infinity();
  for (int k = 0; k < f.count; ++k) best = std::max(best, d.dot(f.p[k]));
  return best;
}

// Static convex bodies that every other body lies above, deeper than a resting contact at most:
// lit from above they can shade nothing but themselves, and a convex body does not shade its own
// lit faces. Such a ground is left out of the shadow pass (it covered the whole map, drawn every
// frame for nothing). Any part of another body below its top lies inside it, or (beside it,
// within kRestingDepth of the top) in a sliver its side could have shaded; both are invisible.
void groundsCastNoShadow(const Model& model, const State& state, const Vec3f& lightDirection,
                         std::vector<Instance>& solids) {
  constexpr double kRestingDepth = 0.05;  // [m]
  if (lightDirection.y() >= 0) return;
  const size_t n = model.bodies.size();
  std::vector<double> bottom(n);
  // The two lowest bottoms, so each body can be compared with the lowest of the others.
  double low1 = std::numeric_limits<double>::infinity(), low2 = low1;
  size_t lowest = n;
  for (size_t i = 0; i < n; ++i) {
    bottom[i] = -reach(model.bodies[i].shape, state.bodies[i].pose(), -Vec3::UnitY());
    if (bottom[i] < low1) {
      low2 = low1;
      low1 = bottom[i];
      lowest = i;
    } else if (bottom[i] < low2) {
      low2 = bottom[i];
    }
  }
  for (Instance& in : solids) {
    if (in.body < 0) continue;
    const size_t i = static_cast<size_t>(in.body);
    const Shape& shape = model.bodies[i].shape;
    if (!model.bodies[i].isStatic || shape.type == ShapeType::Plane || shape.type == ShapeType::TriangleMesh) continue;
    const double top = reach(shape, state.bodies[i].pose(), Vec3::UnitY());
    if ((i == lowest ? low2 : low1) >= top - kRestingDepth) in.flags |= kNoShadow;
  }
}

}  // namespace

// ---- camera ----

Mat4f Camera::view() const {
  const Vec3f f = (target - eye).normalized();
  Vec3f s = f.cross(up);
  if (s.norm() < 1e-6f) s = f.cross(Vec3f::UnitZ());  // looking straight down
  s.normalize();
  const Vec3f u = s.cross(f);
  Mat4f m = Mat4f::Identity();
  m.block<1, 3>(0, 0) = s.transpose();
  m.block<1, 3>(1, 0) = u.transpose();
  m.block<1, 3>(2, 0) = -f.transpose();
  m(0, 3) = -s.dot(eye);
  m(1, 3) = -u.dot(eye);
  m(2, 3) = f.dot(eye);
  return m;
}

Mat4f Camera::projection(float aspect) const {
  float halfTan = std::tan(0.5f * fovY * static_cast<float>(kDegree));
  if (aspect < fitAspect) halfTan *= fitAspect / aspect;  // same horizontal extent as the preset's view
  const float t = 1.0f / halfTan;
  Mat4f m = Mat4f::Zero();
  m(0, 0) = t / aspect;
  m(1, 1) = t;
  m(2, 2) = (zFar + zNear) / (zNear - zFar);
  m(2, 3) = 2 * zFar * zNear / (zNear - zFar);
  m(3, 2) = -1;
  return m;
}

CameraPreset fittedCamera(const Model& model, const State& state) {
  Eigen::AlignedBox3d box;
  for (size_t i = 0; i < model.bodies.size(); ++i) {
    if (model.bodies[i].isStatic) continue;
    const double r = model.bodies[i].shape.boundingRadius();
    box.extend(state.bodies[i].x - Vec3::Constant(r));
    box.extend(state.bodies[i].x + Vec3::Constant(r));
  }
  CameraPreset c;
  c.name = "fitted";
  c.yaw = 30;
  c.pitch = 20;
  if (box.isEmpty()) return c;
  c.target = box.center();
  const double r = std::max(0.5, 0.5 * box.diagonal().norm());
  c.distance = 1.15 * r / std::sin(0.5 * c.fovY * kDegree);
  return c;
}

CameraPreset chooseCamera(const Scene& scene, const CameraOptions& o) {
  CameraPreset c;
  if (!o.preset.empty()) {
    auto it = std::find_if(scene.cameras.begin(), scene.cameras.end(),
                           [&](const CameraPreset& p) { return p.name == o.preset; });
    if (it == scene.cameras.end()) {
      std::string names;
      for (const CameraPreset& p : scene.cameras) names += (names.empty() ? "" : ", ") + p.name;
      throw std::invalid_argument("--camera: " + scene.file + " has no camera \"" + o.preset + "\" (it has: " +
                                  (names.empty() ? std::string("none; leave --camera out for a fitted view") : names) +
                                  ")");
    }
    c = *it;
  } else if (!scene.cameras.empty()) {
    c = scene.cameras.front();
  } else {
    c = fittedCamera(scene.model, scene.initial);
  }
  if (o.yaw) c.yaw = *o.yaw;
  if (o.pitch) c.pitch = *o.pitch;
  if (o.distance) c.distance = *o.distance;
  if (o.fov) c.fovY = *o.fov;
  if (o.target) c.target = *o.target;
  if (o.follow) {
    if (!o.follow->empty() && scene.model.bodyIndex(*o.follow) < 0)
      throw std::invalid_argument("--follow: " + scene.file + " has no body \"" + *o.follow + "\"");
    c.follow = *o.follow;
  }
  return c;
}

Camera placeCamera(const CameraPreset& p, const Model& model, const State& state, double orbit) {
  Camera cam;
  Vec3 target = p.target;
  if (!p.follow.empty()) {
    const int b = model.bodyIndex(p.follow);
    if (b >= 0) target = state.bodies[static_cast<size_t>(b)].x;
  }
  // Yaw about +Y with 0 looking along -Z: the eye sits on +Z, turned by yaw, raised by pitch.
  const double yaw = (p.yaw + orbit * state.time) * kDegree, pitch = p.pitch * kDegree;
  const Vec3 offset(std::cos(pitch) * std::sin(yaw), std::sin(pitch), std::cos(pitch) * std::cos(yaw));
  cam.target = target.cast<float>();
  cam.eye = (target + p.distance * offset).cast<float>();
  cam.fovY = static_cast<float>(p.fovY);
  cam.zNear = static_cast<float>(std::max(0.01, p.distance * 0.01));
  cam.zFar = static_cast<float>(p.distance * 20 + 200);
  return cam;
}

// ---- colours ----

Vec3f bodyColour(int index) { return hsv(0.08f + 0.618034f * static_cast<float>(index), 0.55f, 0.92f); }

Vec3f groupColour(int group, int member) {
  // The group's hue; members differ in brightness so neighbours in a ragdoll stay apart.
  const float shade = 0.72f + 0.26f * (0.618034f * static_cast<float>(member) - std::floor(0.618034f * static_cast<float>(member)));
  return hsv(0.08f + 0.618034f * static_cast<float>(group), 0.6f, shade);
}

Vec3f rampColour(double t) {
  static const Vec3f stops[] = {{0.15f, 0.3f, 0.95f}, {0.1f, 0.8f, 0.9f}, {0.2f, 0.85f, 0.25f},
                                {0.95f, 0.85f, 0.1f}, {0.95f, 0.15f, 0.1f}};
  if (!(t > 0)) return stops[0];  // also NaN
  if (t >= 1) return stops[4];
  const double x = t * 4;
  const int k = static_cast<int>(x);
  const float f = static_cast<float>(x - k);
  return (1 - f) * stops[k] + f * stops[k + 1];
}

Vec3f staticColour() { return {0.56f, 0.57f, 0.6f}; }
Vec3f normalImpulseColour() { return {1.0f, 0.55f, 0.08f}; }
Vec3f frictionImpulseColour() { return {0.25f, 1.0f, 0.3f}; }
Vec3f jointErrorColour() { return {1.0f, 0.08f, 0.08f}; }

std::optional<ColourMode> parseColourMode(const std::string& s) {
  if (s == "auto") return ColourMode::Auto;
  if (s == "body") return ColourMode::Body;
  if (s == "group") return ColourMode::Group;
  if (s == "speed") return ColourMode::Speed;
  if (s == "activity" || s == "sleep") return ColourMode::Activity;
  if (s == "error") return ColourMode::Error;
  return std::nullopt;
}

const char* colourModeName(ColourMode m) {
  switch (m) {
    case ColourMode::Auto: return "auto";
    case ColourMode::Body: return "body";
    case ColourMode::Group: return "group";
    case ColourMode::Speed: return "speed";
    case ColourMode::Activity: return "activity";
    case ColourMode::Error: return "error";
  }
  return "?";
}

// ---- text ----

std::string sceneLine(const Scene& scene) {
  return scene.model.name + ": " + std::to_string(scene.model.dynamicCount()) + " bodies, " +
         std::to_string(scene.model.joints.size()) + " joints";
}

// ---- builder ----

std::vector<double> bodyErrors(const Model& model, const Snapshot& snap) {
  const State& state = snap.state;
  std::vector<double> err(model.bodies.size(), 0.0);
  for (const ManifoldSnap& m : snap.manifolds)
    for (int k = m.first; k < m.first + m.count; ++k) {
      const double pen = snap.contacts[static_cast<size_t>(k)].depth;
      err[static_cast<size_t>(m.a)] = std::max(err[static_cast<size_t>(m.a)], pen);
      err[static_cast<size_t>(m.b)] = std::max(err[static_cast<size_t>(m.b)], pen);
    }
  const bool measured = snap.joints.size() == model.joints.size();  // else measure them here
  for (size_t k = 0; k < model.joints.size(); ++k) {
    const Joint& j = model.joints[k];
    const double e = measured ? static_cast<double>(snap.joints[k].error)
                              : jointError(j, state.bodies[static_cast<size_t>(j.bodyA)].pose(),
                                           state.bodies[static_cast<size_t>(j.bodyB)].pose());
    err[static_cast<size_t>(j.bodyA)] = std::max(err[static_cast<size_t>(j.bodyA)], e);
    err[static_cast<size_t>(j.bodyB)] = std::max(err[static_cast<size_t>(j.bodyB)], e);
  }
  return err;
}

double impulseTime(const SolverSettings& settings) {
  return subSteps(settings.algorithm) ? settings.dt / settings.substeps : settings.dt;
}

double autoForceScale(const Model& model, const Snapshot& snap, double impulseTime) {
  double mass = 0, radius = 0;
  for (const Body& b : model.bodies)
    if (!b.isStatic && b.mass > mass) {
      mass = b.mass;
      radius = b.shape.boundingRadius();
    }
  double tau = impulseTime;
  if (!(tau > 0))
    tau = snap.state.step > 0 && snap.state.time > 0 ? snap.state.time / static_cast<double>(snap.state.step) : 1.0 / 60;
  const double weight = mass * model.gravity.norm() * tau;  // [N s]
  if (!(weight > 0) || !(radius > 0) || !std::isfinite(weight)) return 1;  // nothing rests: any scale
  return niceFloor(radius / weight);
}

std::string forceLegend(double scale, double about) {
  const double len = niceFloor(about), impulse = len / scale;
  std::string l = len >= 1 ? fmt("%g m", len) : len >= 0.01 ? fmt("%g cm", len * 1e2) : fmt("%g mm", len * 1e3);
  return "arrow " + l + " = " + fmt("%.3g N s", impulse);
}

DrawList buildDrawList(const Model& model, const Snapshot& snap, const Camera& camera, const ViewOptions& view,
                       const HudInfo& hud) {
  const State& state = snap.state;
  DrawList dl;
  dl.camera = camera;
  shadowBounds(model, state, dl.boundsCentre, dl.boundsRadius);

  ColourMode mode = view.colour;
  if (mode == ColourMode::Auto) {
    // Groups tell ragdolls or chains apart; one group (a single stack) would paint everything alike.
    std::set<int> groups;
    for (const Body& b : model.bodies)
      if (!b.isStatic && b.group >= 0) groups.insert(b.group);
    mode = groups.size() >= 2 ? ColourMode::Group : ColourMode::Body;
  }
  std::vector<double> errors;
  if (mode == ColourMode::Error) errors = bodyErrors(model, snap);

  std::map<int, int> membersSoFar;  // per group, for shading members apart
  std::vector<int> highlighted(model.bodies.size(), 0);
  for (const std::string& name : view.highlight) {
    const int b = model.bodyIndex(name);
    if (b >= 0) highlighted[static_cast<size_t>(b)] = 1;
  }

  int dynamicIndex = 0;
  for (size_t i = 0; i < model.bodies.size(); ++i) {
    const Body& body = model.bodies[i];
    const BodyState& bs = state.bodies[i];
    const Shape& sh = body.shape;
    Instance in;
    in.body = static_cast<int>(i);
    in.position = bs.x.cast<float>();
    in.rotation = bs.q.cast<float>().normalized();
    switch (sh.type) {
      case ShapeType::Box:
        in.mesh = kBoxMesh;
        in.scale = sh.halfExtents.cast<float>();
        break;
      case ShapeType::Sphere:
        in.mesh = kSphereMesh;
        in.scale = Vec3f::Constant(static_cast<float>(sh.radius));
        break;
      case ShapeType::Capsule:
        in.mesh = kCapsuleMesh;
        in.scale = Vec3f::Constant(static_cast<float>(sh.radius));
        in.stretch = static_cast<float>(sh.halfHeight);
        break;
      case ShapeType::Cylinder:
        in.mesh = kCylinderMesh;
        in.scale = Vec3f(static_cast<float>(sh.radius), static_cast<float>(sh.halfHeight), static_cast<float>(sh.radius));
        break;
      case ShapeType::ConvexMesh:
      case ShapeType::TriangleMesh: {
        if (!sh.mesh) continue;
        auto it = std::find(dl.meshes.begin(), dl.meshes.end(), sh.mesh);
        in.mesh = kFirstCustomMesh + static_cast<int>(it - dl.meshes.begin());
        if (it == dl.meshes.end()) dl.meshes.push_back(sh.mesh);
        break;
      }
      case ShapeType::Plane: {
        // A square around the point of the plane nearest the camera's target, big enough to
        // reach the horizon; the grid and the fog make its edge invisible.
        const Vec3f n = sh.normal.cast<float>().normalized();
        const Vec3f onPlane = camera.target - (n.dot(camera.target) - static_cast<float>(sh.offset)) * n;
        in.mesh = kQuadMesh;
        in.position = onPlane;
        in.rotation = fromY(n);
        const float size = std::max(200.0f, 4 * (camera.eye - camera.target).norm());
        in.scale = Vec3f(size, 1, size);
        in.flags |= kNoShadow;
        break;
      }
    }
    Vec3f colour;
    if (body.isStatic) {
      colour = staticColour();
      in.flags |= kGrid;
    } else {
      switch (mode) {
        case ColourMode::Group:
          colour = body.group >= 0 ? groupColour(body.group, membersSoFar[body.group]++) : bodyColour(dynamicIndex);
          break;
        case ColourMode::Speed: colour = rampColour(bs.v.norm() / view.speedScale); break;
        case ColourMode::Activity: {
          const bool rest = bs.v.norm() < view.restSpeed && bs.w.norm() < view.restSpeed;
          const bool asleep = std::binary_search(snap.asleep.begin(), snap.asleep.end(), static_cast<int32_t>(i));
          colour = asleep ? Vec3f(0.22f, 0.25f, 0.42f) : rest ? Vec3f(0.45f, 0.52f, 0.66f) : Vec3f(1.0f, 0.55f, 0.12f);
          break;
        }
        case ColourMode::Error: colour = rampColour(0.5 + 0.5 * std::min(1.0, errors[i] / view.errorScale)); break;
        default: colour = bodyColour(dynamicIndex); break;
      }
      ++dynamicIndex;
    }
    in.colour = Vec4f(colour.x(), colour.y(), colour.z(), 1.0f);
    in.highlight = highlighted[i] ? 1.0f : 0.0f;
    dl.solids.push_back(in);
  }
  groundsCastNoShadow(model, state, dl.lightDirection, dl.solids);

  // Overlays are sized with the view so they read the same from near and far.
  const float viewSize = (camera.eye - camera.target).norm() * std::tan(0.5f * camera.fovY * static_cast<float>(kDegree));
  const float dotR = 0.012f * viewSize, lineR = 0.0035f * viewSize, normalLen = 0.08f * viewSize;
  if (view.contacts) {
    for (const ContactSnap& c : snap.contacts) {
      const bool touching = c.depth >= 0;  // speculative points are still apart
      dl.overlays.push_back(dot(c.point, dotR, touching ? Vec3f(1.0f, 0.9f, 0.1f) : Vec3f(0.6f, 0.6f, 0.6f)));
      // The normal points from B into A, as the solver uses it.
      dl.overlays.push_back(segment(c.point, c.point + normalLen * c.normal, lineR, Vec3f(0.1f, 0.95f, 1.0f)));
    }
  }
  const double forceScale = view.forceScale > 0 ? view.forceScale : autoForceScale(model, snap, view.impulseTime);
  if (view.forces) {
    // The impulses on a body of each pair: on A (λn along the normal, from B into A; friction in
    // the contact plane), or on B, the opposite ones, when A is static: a ground is not pushed.
    const float k = static_cast<float>(forceScale), arrowR = 1.4f * lineR;
    for (const ManifoldSnap& m : snap.manifolds) {
      if (m.count <= 0) continue;
      const float sign = model.bodies[static_cast<size_t>(m.a)].isStatic ? -1.0f : 1.0f;
      Vec3f centre = Vec3f::Zero();
      for (int i = m.first; i < m.first + m.count; ++i) {
        const ContactSnap& c = snap.contacts[static_cast<size_t>(i)];
        centre += c.point;
        if (c.normalImpulse > 0)
          arrow(dl.overlays, c.point, c.point + sign * k * c.normalImpulse * c.normal, arrowR, normalImpulseColour());
      }
      centre /= static_cast<float>(m.count);
      arrow(dl.overlays, centre, centre + sign * k * m.friction, arrowR, frictionImpulseColour());
    }
  }
  if (view.jointErrors) {
    for (const Joint& j : model.joints) {
      const Vec3f wa = state.bodies[static_cast<size_t>(j.bodyA)].pose().apply(j.localAnchorA).cast<float>();
      const Vec3f wb = state.bodies[static_cast<size_t>(j.bodyB)].pose().apply(j.localAnchorB).cast<float>();
      // Shorter than the line is wide, a segment would be a dot of no length: a joint that holds.
      if ((wa - wb).norm() >= lineR) dl.overlays.push_back(segment(wa, wb, 2.5f * lineR, jointErrorColour()));
    }
  }
  if (view.joints) {
    for (const Joint& j : model.joints) {
      const BodyState& a = state.bodies[static_cast<size_t>(j.bodyA)];
      const BodyState& b = state.bodies[static_cast<size_t>(j.bodyB)];
      const Vec3f wa = a.pose().apply(j.localAnchorA).cast<float>(), wb = b.pose().apply(j.localAnchorB).cast<float>();
      const Vec3f armColour(1.0f, 0.35f, 0.85f);
      dl.overlays.push_back(segment(a.x.cast<float>(), wa, lineR, armColour));
      dl.overlays.push_back(segment(b.x.cast<float>(), wb, lineR, armColour));
      dl.overlays.push_back(dot(wa, dotR, Vec3f(1.0f, 0.2f, 0.7f)));
      if ((wa - wb).norm() > 0.5f * dotR) dl.overlays.push_back(dot(wb, dotR, Vec3f(1.0f, 0.6f, 0.9f)));
      if (j.type == JointType::Hinge || j.type == JointType::ConeTwist || j.type == JointType::Motor) {
        const Vec3f axis = (a.q * j.localAxisA).cast<float>().normalized();
        dl.overlays.push_back(segment(wa - normalLen * axis, wa + normalLen * axis, lineR, Vec3f(1.0f, 1.0f, 1.0f)));
      }
    }
  }

  if (view.hud) {
    const Vec4f white(1, 1, 1, 1), grey(0.85f, 0.88f, 0.92f, 1), red(1.0f, 0.35f, 0.3f, 1);
    if (!hud.scene.empty()) dl.hud.push_back({hud.scene, white});
    if (!hud.settings.empty()) dl.hud.push_back({hud.settings, grey});
    std::string line = fmt("t = %.3f s", hud.time);
    if (std::isfinite(hud.stepMs)) line += fmt("    step %.2f ms", hud.stepMs);
    dl.hud.push_back({line, grey});
    if (!hud.status.empty()) dl.hud.push_back({hud.status, red});
    std::string legend;
    switch (mode) {
      case ColourMode::Speed: legend = fmt("colour: speed, blue 0 to red %g m/s", view.speedScale); break;
      case ColourMode::Activity:
        legend = fmt("colour: orange moving, blue-grey at rest (< %g m/s)", view.restSpeed) +
                 (snap.asleep.empty() ? "" : ", dark blue asleep");
        break;
      case ColourMode::Error: legend = fmt("colour: constraint error, green 0 to red %g mm", view.errorScale * 1e3); break;
      default: break;
    }
    if (!legend.empty()) dl.footer.push_back({legend, grey});
    if (view.contacts) dl.footer.push_back({"contacts: points yellow, normals cyan", grey});
    if (view.joints) dl.footer.push_back({"joints: anchors and arms magenta, axes white", grey});
    auto rgba = [](const Vec3f& c) { return Vec4f(c.x(), c.y(), c.z(), 1); };
    if (view.forces) {
      dl.footer.push_back({"impulses: " + forceLegend(forceScale, 0.15 * viewSize), grey});
      dl.footer.push_back({"  normal (λn at each contact point)", rgba(normalImpulseColour())});
      dl.footer.push_back({"  friction (per touching pair)", rgba(frictionImpulseColour())});
    }
    if (view.jointErrors) dl.footer.push_back({"joint errors: anchor A to anchor B", rgba(jointErrorColour())});
  }
  return dl;
}

}  // namespace substep::render
