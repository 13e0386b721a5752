#include "lab/ode_peer.h"
#include "lab/peer_shapes.h"

#include "physics/constraints/joints.h"

#include <ode/ode.h>
#include <ode/version.h>

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <mutex>
#include <stdexcept>
#include <utility>
#include <vector>

namespace substep::lab {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kMaxPointsPerPair = 8;
constexpr double kBounceSpeed = 1.0;  // [m/s]: substep's restitution_threshold default

// ODE's errors and debug checks end the process by default; here they end the run with the message.
void raise(int, const char* msg, va_list ap) {
  char buf[512];
  std::vsnprintf(buf, sizeof buf, msg, ap);
  throw std::runtime_error(std::string("ODE: ") + buf);
}
void quiet(int, const char*, va_list) {}  // its warnings ("LCP internal error, s <= 0") are not ours to print

void initOde() {
  static std::once_flag once;
  std::call_once(once, [] {
    dInitODE2(0);
    dSetErrorHandler(raise);
    dSetDebugHandler(raise);
    dSetMessageHandler(quiet);
  });
  dAllocateODEDataForThread(dAllocateMaskAll);  // per thread that collides; a no-op when done
}

Quat capsuleTurn() { return Quat(Eigen::AngleAxisd(-kPi / 2, Vec3::UnitX())); }  // ODE's local Z onto our Y

void toOde(const Quat& q, dQuaternion out) {
  out[0] = q.w();
  out[1] = q.x();
  out[2] = q.y();
  out[3] = q.z();
}

// ODE's hinge stops are angles in [-pi, pi] from the start; ODE measures the angle of A from B
// (B turned by +a about the axis reads -a; checked against dJointGetHingeAngle), ours of B from A.
bool hingeStops(const Joint& j, const State& initial, double& lo, double& hi) {
  const double a0 = hingeAngle(j, initial.bodies[static_cast<size_t>(j.bodyA)].pose(), initial.bodies[static_cast<size_t>(j.bodyB)].pose());
  lo = a0 - j.upper;
  hi = a0 - j.lower;
  return lo >= -kPi && hi <= kPi;
}

struct Material {
  double friction, restitution;
  bool isStatic;
  const Body* body;
};

class OdeEngine final : public Engine {
 public:
  OdeEngine(const Model& model, const State& initial, const OdeSettings& settings);
  ~OdeEngine() override;
  OdeEngine(const OdeEngine&) = delete;
  OdeEngine& operator=(const OdeEngine&) = delete;

  void advance() override {
    measuring_ = false;
    dSpaceCollide(space_, this, &OdeEngine::near);
    if (settings_.quick)
      dWorldQuickStep(world_, settings_.dt);
    else
      dWorldStep(world_, settings_.dt);
    dJointGroupEmpty(contacts_);
  }
  Step status() override;
  const State& state() const override { return s_; }
  // The depths at the current coordinates: a collision pass of its own (not timed), since ODE keeps
  // no contacts between steps.
  ContactDepths depths() const override {
    auto* self = const_cast<OdeEngine*>(this);
    self->measuring_ = true;
    self->measured_ = ContactDepths{};
    dSpaceCollide(space_, self, &OdeEngine::near);
    self->measuring_ = false;
    return measured_;
  }

 private:
  static void near(void* data, dGeomID g1, dGeomID g2);
  bool admitted(size_t i, size_t k) const {
    const Material &a = materials_[i], &b = materials_[k];
    if (a.isStatic && b.isStatic) return false;
    if (!mayTouch(*a.body, *b.body)) return false;
    return !std::binary_search(excluded_.begin(), excluded_.end(), std::make_pair(std::min(i, k), std::max(i, k)));
  }

  OdeSettings settings_;
  dWorldID world_ = nullptr;
  dSpaceID space_ = nullptr;
  dJointGroupID contacts_ = nullptr;
  std::vector<dBodyID> bodies_;  // null for static bodies
  std::vector<Material> materials_;
  std::vector<std::pair<size_t, size_t>> excluded_;  // joined pairs that do not collide, sorted
  State s_;
  bool measuring_ = false;
  ContactDepths measured_;
};

OdeEngine::OdeEngine(const Model& model, const State& initial, const OdeSettings& settings) : settings_(settings), s_(initial) {
  if (initial.bodies.size() != model.bodies.size()) throw std::invalid_argument("ODE peer: state and model differ");
  initOde();
  // QuickStep reorders its rows with ODE's one global random generator, which every step moves on:
  // started at the same seed, a run is the same whatever ran before it in the process (a sweep's
  // record re-runs bit for bit in another).
  dRandSetSeed(0);
  world_ = dWorldCreate();
  space_ = dHashSpaceCreate(nullptr);
  contacts_ = dJointGroupCreate(0);
  dWorldSetGravity(world_, model.gravity.x(), model.gravity.y(), model.gravity.z());
  dWorldSetERP(world_, settings.erp);
  dWorldSetCFM(world_, settings.cfm);
  dWorldSetQuickStepNumIterations(world_, settings.iterations);
  dWorldSetQuickStepW(world_, settings.sor);
  dWorldSetContactSurfaceLayer(world_, settings.layer);
  dWorldSetAutoDisableFlag(world_, 0);

  for (size_t i = 0; i < model.bodies.size(); ++i) {
    const Body& b = model.bodies[i];
    const BodyState& s = initial.bodies[i];
    materials_.push_back(Material{b.friction, b.restitution, b.isStatic, &b});
    dBodyID body = nullptr;
    if (!b.isStatic) {
      body = dBodyCreate(world_);
      dMass m;
      // Our body frame is the centre of mass and the principal axes: the inertia is our diagonal.
      dMassSetParameters(&m, b.mass, 0, 0, 0, b.inertia.x(), b.inertia.y(), b.inertia.z(), 0, 0, 0);
      dBodySetMass(body, &m);
      dBodySetPosition(body, s.x.x(), s.x.y(), s.x.z());
      dQuaternion q;
      toOde(s.q.normalized(), q);
      dBodySetQuaternion(body, q);
      dBodySetLinearVel(body, s.v.x(), s.v.y(), s.v.z());
      const Vec3 w = s.worldAngularVelocity();
      dBodySetAngularVel(body, w.x(), w.y(), w.z());
      dBodySetGyroscopicMode(body, settings.gyroscopic ? 1 : 0);
    }
    bodies_.push_back(body);

    const Shape& sh = b.shape;
    dGeomID g = nullptr;
    bool turned = false;
    switch (sh.type) {
      case ShapeType::Sphere: g = dCreateSphere(space_, sh.radius); break;
      case ShapeType::Box: g = dCreateBox(space_, 2 * sh.halfExtents.x(), 2 * sh.halfExtents.y(), 2 * sh.halfExtents.z()); break;
      case ShapeType::Capsule:  // ODE's length leaves out the caps: the distance between the cap centres
        g = dCreateCapsule(space_, sh.radius, 2 * sh.halfHeight);
        turned = true;
        break;
      case ShapeType::Cylinder:
        g = dCreateCylinder(space_, sh.radius, 2 * sh.halfHeight);
        turned = true;
        break;
      case ShapeType::Plane: {  // static (odeUnsupported): n . x = d in the world
        const Vec3 n = (s.q * sh.normal).normalized();
        g = dCreatePlane(space_, n.x(), n.y(), n.z(), sh.offset + n.dot(s.x));
        break;
      }
      default: throw std::invalid_argument("ODE peer: body \"" + b.name + "\": shape not mapped");
    }
    dGeomSetData(g, reinterpret_cast<void*>(static_cast<std::uintptr_t>(i)));
    if (sh.type == ShapeType::Plane) continue;
    if (body) {
      dGeomSetBody(g, body);
      if (turned) {
        dMatrix3 R;
        dRFromAxisAndAngle(R, 1, 0, 0, -kPi / 2);
        dGeomSetOffsetRotation(g, R);
      }
    } else {
      dGeomSetPosition(g, s.x.x(), s.x.y(), s.x.z());
      dQuaternion q;
      toOde(turned ? Quat(s.q.normalized() * capsuleTurn()) : s.q.normalized(), q);
      dGeomSetQuaternion(g, q);
    }
  }

  for (const Joint& j : model.joints) {
    const size_t a = static_cast<size_t>(j.bodyA), b = static_cast<size_t>(j.bodyB);
    if (!j.collide) excluded_.emplace_back(std::min(a, b), std::max(a, b));
    if (!bodies_[a] && !bodies_[b]) continue;  // between static bodies: nothing to hold
    const Pose A = initial.bodies[a].pose();
    const Vec3 anchor = A.apply(j.localAnchorA);
    dJointID joint = nullptr;
    switch (j.type) {
      case JointType::Ball:
        joint = dJointCreateBall(world_, nullptr);
        dJointAttach(joint, bodies_[a], bodies_[b]);
        dJointSetBallAnchor(joint, anchor.x(), anchor.y(), anchor.z());
        break;
      case JointType::Hinge: {
        joint = dJointCreateHinge(world_, nullptr);
        dJointAttach(joint, bodies_[a], bodies_[b]);
        dJointSetHingeAnchor(joint, anchor.x(), anchor.y(), anchor.z());
        const Vec3 axis = A.rotate(j.localAxisA).normalized();
        dJointSetHingeAxis(joint, axis.x(), axis.y(), axis.z());
        double lo = 0, hi = 0;
        if (j.hasLimits && hingeStops(j, initial, lo, hi)) {
          dJointSetHingeParam(joint, dParamLoStop, lo);
          dJointSetHingeParam(joint, dParamHiStop, hi);
        }
        break;
      }
      case JointType::Fixed:
        joint = dJointCreateFixed(world_, nullptr);
        dJointAttach(joint, bodies_[a], bodies_[b]);
        dJointSetFixed(joint);
        break;
      default: throw std::invalid_argument("ODE peer: joint \"" + j.name + "\" is not mapped");
    }
  }
  std::sort(excluded_.begin(), excluded_.end());
}

OdeEngine::~OdeEngine() {
  if (contacts_) dJointGroupDestroy(contacts_);
  if (space_) dSpaceDestroy(space_);  // and its geoms
  if (world_) dWorldDestroy(world_);  // and its bodies and joints
}

void OdeEngine::near(void* data, dGeomID g1, dGeomID g2) {
  auto* self = static_cast<OdeEngine*>(data);
  const size_t i = static_cast<size_t>(reinterpret_cast<std::uintptr_t>(dGeomGetData(g1)));
  const size_t k = static_cast<size_t>(reinterpret_cast<std::uintptr_t>(dGeomGetData(g2)));
  if (!self->admitted(i, k)) return;
  dContactGeom points[kMaxPointsPerPair];
  const int n = dCollide(g1, g2, kMaxPointsPerPair, points, sizeof(dContactGeom));
  if (self->measuring_) {
    for (int p = 0; p < n; ++p) {
      const double depth = points[p].depth;
      if (depth <= 0) continue;
      self->measured_.deepest = std::max(self->measured_.deepest, depth);
      self->measured_.sumSquares += depth * depth;
      ++self->measured_.points;
    }
    return;
  }
  const Material &a = self->materials_[i], &b = self->materials_[k];
  const double mu = std::sqrt(a.friction * b.friction), e = std::max(a.restitution, b.restitution);
  for (int p = 0; p < n; ++p) {
    dContact c{};
    c.geom = points[p];
    // dContactApprox1: Coulomb's mu times the normal force on each of two friction directions (ODE's
    // plain mode would take mu as a force).
    c.surface.mode = dContactApprox1 | (e > 0 ? dContactBounce : 0);
    c.surface.mu = mu;
    c.surface.bounce = e;
    c.surface.bounce_vel = kBounceSpeed;
    const dJointID joint = dJointCreateContact(self->world_, self->contacts_, &c);
    dJointAttach(joint, dGeomGetBody(g1), dGeomGetBody(g2));
  }
}

Engine::Step OdeEngine::status() {
  for (size_t i = 0; i < bodies_.size(); ++i) {
    const dBodyID b = bodies_[i];
    if (!b) continue;
    BodyState& s = s_.bodies[i];
    const dReal* x = dBodyGetPosition(b);
    const dReal* q = dBodyGetQuaternion(b);
    const dReal* v = dBodyGetLinearVel(b);
    const dReal* w = dBodyGetAngularVel(b);
    s.x = Vec3(x[0], x[1], x[2]);
    s.q = Quat(q[0], q[1], q[2], q[3]).normalized();
    s.v = Vec3(v[0], v[1], v[2]);
    s.w = s.q.conjugate() * Vec3(w[0], w[1], w[2]);  // ours is in the body frame
  }
  s_.step += 1;
  s_.time = static_cast<double>(s_.step) * settings_.dt;
  if (s_.finite()) return {};
  return Step{false, false, "an ODE body's state is not finite"};
}

}  // namespace

namespace {

std::string modelUnsupported(const Model& model) {
  if (std::string why = unmappedBody(model, "ODE"); !why.empty()) return why;
  for (const Joint& j : model.joints) {
    if (j.type == JointType::ConeTwist)
      return "joint \"" + j.name + "\" is a cone_twist (ODE has no swing cone; the ODE peer maps ball, hinge and fixed joints)";
    if (j.type == JointType::Spring || j.type == JointType::Motor)
      return "joint \"" + j.name + "\" is a " + jointTypeName(j.type) + " (the ODE peer maps ball, hinge and fixed joints)";
    if (j.type == JointType::Hinge && j.hasMotor) return "joint \"" + j.name + "\" is a hinge with a motor (not mapped)";
  }
  return {};
}

}  // namespace

std::string odeUnsupported(const Model& model, const State& initial) {
  std::string why = modelUnsupported(model);
  if (!why.empty()) return why;
  for (const Joint& j : model.joints) {
    double lo = 0, hi = 0;
    if (j.type == JointType::Hinge && j.hasLimits && !hingeStops(j, initial, lo, hi))
      return "hinge \"" + j.name + "\": its limits reach beyond half a turn from the start (ODE's stops are in [-pi, pi])";
  }
  return {};
}

std::string odeVersion() { return std::string(dODE_VERSION) + (sizeof(dReal) == 8 ? " (double)" : " (float)"); }

std::unique_ptr<Engine> makeOdeEngine(const Model& model, const State& initial, const OdeSettings& settings) {
  const std::string why = odeUnsupported(model, initial);
  if (!why.empty()) throw std::invalid_argument("ODE peer: " + why);
  return std::make_unique<OdeEngine>(model, initial, settings);
}

}  // namespace substep::lab
