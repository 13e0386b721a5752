#include "lab/bullet_peer.h"
#include "lab/peer_shapes.h"

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace substep::lab {

namespace {

btVector3 bt(const Vec3& v) { return btVector3(btScalar(v.x()), btScalar(v.y()), btScalar(v.z())); }
btQuaternion bt(const Quat& q) { return btQuaternion(btScalar(q.x()), btScalar(q.y()), btScalar(q.z()), btScalar(q.w())); }
Vec3 fromBt(const btVector3& v) { return Vec3(double(v.x()), double(v.y()), double(v.z())); }

// A joint frame in a body's frame: origin at the anchor, columns x, y = ... as given (unit,
// orthogonal), z = x × y.
btTransform jointFrame(const Vec3& anchor, const Vec3& x, const Vec3& y) {
  const Vec3 z = x.cross(y);
  btTransform t;
  t.setIdentity();
  t.setOrigin(bt(anchor));
  t.setBasis(btMatrix3x3(btScalar(x.x()), btScalar(y.x()), btScalar(z.x()),  //
                         btScalar(x.y()), btScalar(y.y()), btScalar(z.y()),  //
                         btScalar(x.z()), btScalar(y.z()), btScalar(z.z())));
  return t;
}

// The joint's axis and reference direction in one body's frame, made exactly orthonormal.
void axisAndRef(const Vec3& axisIn, const Vec3& refIn, Vec3& axis, Vec3& ref) {
  axis = axisIn.normalized();
  ref = refIn - refIn.dot(axis) * axis;
  if (ref.norm() < 1e-9) {
    Vec3 unused;
    tangentBasis(axis, ref, unused);
  }
  ref.normalize();
}

// Both frames of a joint. `axisColumn` 0: the axis is the frames' x (cone-twist: Bullet twists
// about x), 2: their z (hinge: Bullet turns about z). B's frame is turned by -mid about the axis,
// so that Bullet's zero angle is our angle `mid` (the middle of our limits): Bullet's cone-twist
// limits are symmetric about zero, and with the limits symmetric about zero in Bullet's frames
// too, the mapping does not depend on Bullet's sign convention for the angle.
void jointFrames(const Joint& j, int axisColumn, double mid, btTransform& frameA, btTransform& frameB) {
  Vec3 axA, refA, axB, refB;
  axisAndRef(j.localAxisA, j.localRefA, axA, refA);
  axisAndRef(j.localAxisB, j.localRefB, axB, refB);
  refB = Eigen::AngleAxisd(-mid, axB) * refB;
  if (axisColumn == 0) {
    frameA = jointFrame(j.localAnchorA, axA, refA);
    frameB = jointFrame(j.localAnchorB, axB, refB);
  } else {  // x = ref, y = axis × ref, z = axis
    frameA = jointFrame(j.localAnchorA, refA, axA.cross(refA));
    frameB = jointFrame(j.localAnchorB, refB, axB.cross(refB));
  }
}

// A pair's friction and restitution as ours combine them (physics/collision/manifold.cpp): the
// geometric mean of the frictions, the larger restitution. Bullet's own are products, which would
// make a ramp's 0.4 against a box's 0.4 a friction of 0.16.
btScalar combinedFriction(const btCollisionObject* a, const btCollisionObject* b) {
  return btSqrt(a->getFriction() * b->getFriction());
}
btScalar combinedRestitution(const btCollisionObject* a, const btCollisionObject* b) {
  return btMax(a->getRestitution(), b->getRestitution());
}

std::unique_ptr<btCollisionShape> makeShape(const Shape& s) {
  switch (s.type) {
    case ShapeType::Sphere:
      return std::make_unique<btSphereShape>(btScalar(s.radius));
    case ShapeType::Box:
      return std::make_unique<btBoxShape>(bt(s.halfExtents));
    case ShapeType::Capsule:  // btCapsuleShape: axis along local Y, height = distance between the cap centres
      return std::make_unique<btCapsuleShape>(btScalar(s.radius), btScalar(2 * s.halfHeight));
    case ShapeType::Cylinder:  // btCylinderShape: axis along local Y, half extents (r, h, r)
      return std::make_unique<btCylinderShape>(btVector3(btScalar(s.radius), btScalar(s.halfHeight), btScalar(s.radius)));
    case ShapeType::Plane:
      return std::make_unique<btStaticPlaneShape>(bt(s.normal.normalized()), btScalar(s.offset));
    default:
      return nullptr;
  }
}

}  // namespace

std::string bulletUnsupported(const Model& model) {
  if (std::string why = unmappedBody(model, "Bullet"); !why.empty()) return why;
  for (const Joint& j : model.joints) {
    if (j.type == JointType::Spring || j.type == JointType::Motor)
      return "joint \"" + j.name + "\" is a " + jointTypeName(j.type) +
             " (the Bullet peer maps ball, hinge, cone_twist and fixed joints)";
    if (j.type == JointType::Hinge && j.hasMotor) return "joint \"" + j.name + "\" is a hinge with a motor (not mapped)";
  }
  return {};
}

std::string bulletVersion() {
  const int v = btGetVersion();  // e.g. 324
  return std::to_string(v / 100) + "." + std::to_string(v % 100) + (sizeof(btScalar) == 8 ? " (double)" : " (float)");
}

struct BulletPeer::Impl {
  double dt = 1.0 / 60.0;
  btDefaultCollisionConfiguration config;
  btCollisionDispatcher dispatcher{&config};
  btDbvtBroadphase broadphase;
  btSequentialImpulseConstraintSolver solver;
  btDiscreteDynamicsWorld world{&dispatcher, &broadphase, &solver, &config};
  std::vector<std::unique_ptr<btCollisionShape>> shapes;
  std::vector<std::unique_ptr<btDefaultMotionState>> motionStates;
  std::vector<std::unique_ptr<btRigidBody>> bodies;
  std::vector<std::unique_ptr<btTypedConstraint>> constraints;

  ~Impl() {
    // Remove the constraints and bodies before the world they are in goes away (members die in
    // reverse order).
    for (auto& c : constraints) world.removeConstraint(c.get());
    for (auto& b : bodies) world.removeRigidBody(b.get());
  }
};

BulletPeer::BulletPeer(const Model& model, const State& initial, double dt, int iterations, bool gyroscopic)
    : impl_(std::make_unique<Impl>()) {
  gCalculateCombinedFrictionCallback = combinedFriction;
  gCalculateCombinedRestitutionCallback = combinedRestitution;
  const std::string why = bulletUnsupported(model);
  if (!why.empty()) throw std::invalid_argument("Bullet peer: " + why);
  if (initial.bodies.size() != model.bodies.size()) throw std::invalid_argument("Bullet peer: state and model differ");
  Impl& m = *impl_;
  m.dt = dt;
  m.world.setGravity(bt(model.gravity));
  m.world.getSolverInfo().m_numIterations = iterations;

  for (size_t i = 0; i < model.bodies.size(); ++i) {
    const Body& b = model.bodies[i];
    const BodyState& s = initial.bodies[i];
    std::unique_ptr<btCollisionShape> shape = makeShape(b.shape);
    if (!shape) throw std::invalid_argument("Bullet peer: body \"" + b.name + "\": shape not mapped");
    // Our body frame is the centre of mass and the principal axes, so Bullet's local inertia is
    // our diagonal (not the shape's own calculateLocalInertia(), which for capsules and cylinders
    // is only an approximation).
    const btScalar mass = b.isStatic ? btScalar(0) : btScalar(b.mass);
    const btVector3 inertia = b.isStatic ? btVector3(0, 0, 0) : bt(b.inertia);
    btTransform pose;
    pose.setIdentity();
    pose.setOrigin(bt(s.x));
    pose.setRotation(bt(s.q.normalized()));
    auto motion = std::make_unique<btDefaultMotionState>(pose);
    btRigidBody::btRigidBodyConstructionInfo info(mass, motion.get(), shape.get(), inertia);
    info.m_friction = btScalar(b.friction);
    info.m_restitution = btScalar(b.restitution);
    auto body = std::make_unique<btRigidBody>(info);
    if (!b.isStatic) {
      body->setLinearVelocity(bt(s.v));
      body->setAngularVelocity(bt(s.worldAngularVelocity()));
    }
    body->setActivationState(DISABLE_DEACTIVATION);  // no sleeping, for every body
    body->setFlags(gyroscopic ? BT_ENABLE_GYROSCOPIC_FORCE_IMPLICIT_BODY : 0);
    m.world.addRigidBody(body.get());
    m.shapes.push_back(std::move(shape));
    m.motionStates.push_back(std::move(motion));
    m.bodies.push_back(std::move(body));
  }

  for (const Joint& j : model.joints) {
    btRigidBody& A = *m.bodies.at(static_cast<size_t>(j.bodyA));
    btRigidBody& B = *m.bodies.at(static_cast<size_t>(j.bodyB));
    std::unique_ptr<btTypedConstraint> c;
    btTransform fa, fb;
    switch (j.type) {
      case JointType::Ball:
        c = std::make_unique<btPoint2PointConstraint>(A, B, bt(j.localAnchorA), bt(j.localAnchorB));
        break;
      case JointType::Hinge: {
        // Bullet turns about the frames' z. Limits: ours [lower, upper] about the middle, in
        // frames turned by that middle; Bullet's defaults otherwise (softness 0.9, bias 0.3,
        // relaxation 1).
        const double mid = j.hasLimits ? 0.5 * (j.lower + j.upper) : 0.0;
        jointFrames(j, 2, mid, fa, fb);
        auto h = std::make_unique<btHingeConstraint>(A, B, fa, fb, false);
        if (j.hasLimits) {
          const double half = 0.5 * (j.upper - j.lower);
          h->setLimit(btScalar(-half), btScalar(half));
        }
        c = std::move(h);
        break;
      }
      case JointType::ConeTwist: {
        // Bullet twists about the frames' x; a circular cone (both swing spans = our swing) and a
        // symmetric twist limit |twist| <= (upper - lower)/2 about the middle of ours. Without
        // limits the twist is free (a negative twist span). Bullet's defaults otherwise
        // (softness 1, bias 0.3, relaxation 1).
        const double mid = j.hasLimits ? 0.5 * (j.lower + j.upper) : 0.0;
        jointFrames(j, 0, mid, fa, fb);
        auto ct = std::make_unique<btConeTwistConstraint>(A, B, fa, fb);
        const double twistSpan = j.hasLimits ? 0.5 * (j.upper - j.lower) : -1.0;
        ct->setLimit(btScalar(j.swing), btScalar(j.swing), btScalar(twistSpan));
        c = std::move(ct);
        break;
      }
      case JointType::Fixed:
        jointFrames(j, 0, 0.0, fa, fb);
        c = std::make_unique<btFixedConstraint>(A, B, fa, fb);
        break;
      default:
        throw std::invalid_argument("Bullet peer: joint \"" + j.name + "\" is not mapped");
    }
    m.world.addConstraint(c.get(), /*disableCollisionsBetweenLinkedBodies=*/!j.collide);
    m.constraints.push_back(std::move(c));
  }
}

BulletPeer::~BulletPeer() = default;

void BulletPeer::step() { impl_->world.stepSimulation(btScalar(impl_->dt), 0); }

int BulletPeer::contactPoints() const {
  btCollisionDispatcher& d = impl_->dispatcher;
  int n = 0;
  for (int i = 0; i < d.getNumManifolds(); ++i) n += d.getManifoldByIndexInternal(i)->getNumContacts();
  return n;
}

Vec3 BulletPeer::position(size_t body) const { return fromBt(impl_->bodies.at(body)->getCenterOfMassPosition()); }

Pose BulletPeer::pose(size_t body) const {
  const btTransform& t = impl_->bodies.at(body)->getCenterOfMassTransform();
  const btQuaternion q = t.getRotation();
  return Pose{fromBt(t.getOrigin()), Quat(double(q.w()), double(q.x()), double(q.y()), double(q.z())).normalized()};
}

Vec3 BulletPeer::velocity(size_t body) const { return fromBt(impl_->bodies.at(body)->getLinearVelocity()); }

Vec3 BulletPeer::angularVelocity(size_t body) const { return fromBt(impl_->bodies.at(body)->getAngularVelocity()); }

void BulletPeer::state(State& out) const {
  out.bodies.resize(impl_->bodies.size());
  for (size_t i = 0; i < impl_->bodies.size(); ++i) {
    BodyState& b = out.bodies[i];
    const Pose p = pose(i);
    b.x = p.p;
    b.q = p.q;
    b.v = velocity(i);
    b.w = p.q.conjugate() * angularVelocity(i);
  }
}

BulletPeer::Penetration BulletPeer::penetration() const {
  Penetration p;
  btCollisionDispatcher& d = impl_->dispatcher;
  for (int i = 0; i < d.getNumManifolds(); ++i) {
    const btPersistentManifold* m = d.getManifoldByIndexInternal(i);
    for (int k = 0; k < m->getNumContacts(); ++k) {
      const double depth = -double(m->getContactPoint(k).getDistance());
      if (depth <= 0) continue;
      p.deepest = std::max(p.deepest, depth);
      p.sumSquares += depth * depth;
      ++p.points;
    }
  }
  return p;
}

bool BulletPeer::finite() const {
  for (size_t i = 0; i < impl_->bodies.size(); ++i)
    if (!position(i).allFinite()) return false;
  return true;
}

Engine::Step BulletEngine::status() {
  peer_.state(s_);
  s_.step += 1;
  s_.time = static_cast<double>(s_.step) * dt_;
  if (s_.finite()) return {};
  return Step{false, false, "a Bullet body's state is not finite"};
}

ContactDepths BulletEngine::depths() const {
  const BulletPeer::Penetration p = peer_.penetration();
  return ContactDepths{p.deepest, p.sumSquares, p.points};
}

}  // namespace substep::lab
