#include "app/bench/bullet_peer.h"

#include <btBulletDynamicsCommon.h>

#include <cmath>
#include <stdexcept>
#include <vector>

namespace substep::bench {

std::string bulletUnsupported(const Model& model) {
  if (!model.joints.empty()) return "the scene has joints";
  for (const Body& b : model.bodies)
    if (b.shape.type != ShapeType::Box)
      return "body \"" + b.name + "\" is a " + shapeTypeName(b.shape.type) + " (the Bullet peer builds boxes only)";
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
  std::vector<std::unique_ptr<btBoxShape>> shapes;
  std::vector<std::unique_ptr<btDefaultMotionState>> motionStates;
  std::vector<std::unique_ptr<btRigidBody>> bodies;

  ~Impl() {
    // Remove the bodies before the world they are in goes away (members die in reverse order).
    for (auto& b : bodies) world.removeRigidBody(b.get());
  }
};

BulletPeer::BulletPeer(const Model& model, const State& initial, double dt, int iterations)
    : impl_(std::make_unique<Impl>()) {
  const std::string why = bulletUnsupported(model);
  if (!why.empty()) throw std::invalid_argument("Bullet peer: " + why);
  if (initial.bodies.size() != model.bodies.size()) throw std::invalid_argument("Bullet peer: state and model differ");
  Impl& m = *impl_;
  m.dt = dt;
  m.world.setGravity(btVector3(btScalar(model.gravity.x()), btScalar(model.gravity.y()), btScalar(model.gravity.z())));
  m.world.getSolverInfo().m_numIterations = iterations;

  for (size_t i = 0; i < model.bodies.size(); ++i) {
    const Body& b = model.bodies[i];
    const BodyState& s = initial.bodies[i];
    const Vec3& he = b.shape.halfExtents;
    auto shape = std::make_unique<btBoxShape>(btVector3(btScalar(he.x()), btScalar(he.y()), btScalar(he.z())));
    const btScalar mass = b.isStatic ? btScalar(0) : btScalar(b.mass);
    btVector3 inertia(0, 0, 0);
    if (!b.isStatic) shape->calculateLocalInertia(mass, inertia);
    btTransform pose;
    pose.setIdentity();
    pose.setOrigin(btVector3(btScalar(s.x.x()), btScalar(s.x.y()), btScalar(s.x.z())));
    pose.setRotation(btQuaternion(btScalar(s.q.x()), btScalar(s.q.y()), btScalar(s.q.z()), btScalar(s.q.w())));
    auto motion = std::make_unique<btDefaultMotionState>(pose);
    btRigidBody::btRigidBodyConstructionInfo info(mass, motion.get(), shape.get(), inertia);
    info.m_friction = btScalar(b.friction);
    info.m_restitution = btScalar(b.restitution);
    auto body = std::make_unique<btRigidBody>(info);
    if (!b.isStatic) {
      const Vec3 w = s.worldAngularVelocity();
      body->setLinearVelocity(btVector3(btScalar(s.v.x()), btScalar(s.v.y()), btScalar(s.v.z())));
      body->setAngularVelocity(btVector3(btScalar(w.x()), btScalar(w.y()), btScalar(w.z())));
    }
    body->setActivationState(DISABLE_DEACTIVATION);  // no sleeping, for every body
    m.world.addRigidBody(body.get());
    m.shapes.push_back(std::move(shape));
    m.motionStates.push_back(std::move(motion));
    m.bodies.push_back(std::move(body));
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

Vec3 BulletPeer::position(size_t body) const {
  const btVector3& p = impl_->bodies.at(body)->getCenterOfMassPosition();
  return Vec3(double(p.x()), double(p.y()), double(p.z()));
}

bool BulletPeer::finite() const {
  for (size_t i = 0; i < impl_->bodies.size(); ++i)
    if (!position(i).allFinite()) return false;
  return true;
}

}  // namespace substep::bench
