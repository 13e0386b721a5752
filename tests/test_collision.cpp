// s1: what FCL gives and the manifolds built on it (clipping of supporting features, reduction,
// persistence), and the broadphase's pairs.
#include "physics/collision/broadphase.h"
#include "physics/collision/manifold.h"
#include "physics/collision/narrowphase.h"
#include "physics/collision/raycast.h"
#include "physics/scene_file.h"

#include <fcl/narrowphase/collision.h>
#include <fcl/narrowphase/distance.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

using namespace substep;

namespace {

Shape box(double hx, double hy, double hz) {
  Shape s;
  s.type = ShapeType::Box;
  s.halfExtents = Vec3(hx, hy, hz);
  return s;
}
Shape capsule(double r, double hh) {
  Shape s;
  s.type = ShapeType::Capsule;
  s.radius = r;
  s.halfHeight = hh;
  return s;
}
Shape cylinder(double r, double hh) {
  Shape s = capsule(r, hh);
  s.type = ShapeType::Cylinder;
  return s;
}
// A 10 m square of two triangles at y = 0, facing up: a static triangle-mesh ground.
Shape groundMesh() {
  auto mesh = std::make_shared<Mesh>();
  mesh->vertices = {Vec3(-5, 0, -5), Vec3(5, 0, -5), Vec3(5, 0, 5), Vec3(-5, 0, 5)};
  mesh->triangles = {{0, 2, 1}, {0, 3, 2}};
  Shape m;
  m.type = ShapeType::TriangleMesh;
  m.mesh = mesh;
  return m;
}
Shape sphere(double r) {
  Shape s;
  s.type = ShapeType::Sphere;
  s.radius = r;
  return s;
}
Quat rot(double angle, const Vec3& axis) { return Quat(Eigen::AngleAxisd(angle, axis.normalized())); }
// A unit box named "b<index>" at x, into a model and its state.
void addUnitBox(Model& m, State& s, const Vec3& x) {
  Body b;
  b.name = "b" + std::to_string(m.bodies.size());
  b.shape = box(0.5, 0.5, 0.5);
  m.bodies.push_back(b);
  BodyState bs;
  bs.x = x;
  s.bodies.push_back(bs);
}

// The ground: a static box whose top face is y = 0.
const Shape kGround = box(10, 0.5, 10);
const Pose kGroundPose{Vec3(0, -0.5, 0), Quat::Identity()};

ContactPatch collide(const Shape& a, const Pose& pa, const Shape& b = kGround, const Pose& pb = kGroundPose,
                     double margin = 0.005) {
  Narrowphase np;
  ContactPatch patch;
  np.collide(a, makeCollisionShape(a), pa, b, makeCollisionShape(b), pb, margin, patch);
  return patch;
}

void expectConsistent(const ContactPatch& p) {
  for (int i = 0; i < p.count; ++i) {
    EXPECT_NEAR(p.p[i].n.norm(), 1.0, 1e-9);
    EXPECT_NEAR((p.p[i].pB - p.p[i].pA).dot(p.p[i].n), p.p[i].depth, 1e-9);
  }
}

// A reproducible uniform number in [0, 1) (a 64-bit LCG, Knuth's MMIX constants), advancing seed.
double unitRandom(uint64_t& seed) {
  seed = seed * 6364136223846793005ull + 1442695040888963407ull;
  return static_cast<double>(seed >> 11) / 9007199254740992.0;
}

// The deepest point's depth of a patch (-1e9 for an empty one) [m].
double deepestDepth(const ContactPatch& p) {
  double d = -1e9;
  for (int i = 0; i < p.count; ++i) d = std::max(d, p.p[i].depth);
  return d;
}

}  // namespace

TEST(Narrowphase, BoxRestingOnGroundHasFourCorners) {
  const ContactPatch p = collide(box(0.5, 0.5, 0.5), Pose{Vec3(0.3, 0.49, -0.2), Quat::Identity()});
  ASSERT_EQ(p.count, 4);
  expectConsistent(p);
  for (int i = 0; i < 4; ++i) {
    EXPECT_LT((p.p[i].n - Vec3::UnitY()).norm(), 1e-9);
    EXPECT_NEAR(p.p[i].depth, 0.01, 1e-9);
    EXPECT_NEAR(std::abs(p.p[i].pA.x() - 0.3), 0.5, 1e-9);
    EXPECT_NEAR(std::abs(p.p[i].pA.z() + 0.2), 0.5, 1e-9);
    EXPECT_NEAR(p.p[i].pB.y(), 0.0, 1e-9);
  }
}

TEST(Narrowphase, BoxOnBoxKeepsTheOverlapOfTheFaces) {
  // A unit box shifted by half its width on another: the overlap is a 0.5 x 1 rectangle.
  const ContactPatch p =
      collide(box(0.5, 0.5, 0.5), Pose{Vec3(0.5, 1.49, 0), Quat::Identity()}, box(0.5, 0.5, 0.5), Pose{Vec3(0, 0.5, 0), Quat::Identity()});
  ASSERT_EQ(p.count, 4);
  expectConsistent(p);
  for (int i = 0; i < 4; ++i) {
    EXPECT_GE(p.p[i].pA.x(), -1e-9);
    EXPECT_LE(p.p[i].pA.x(), 0.5 + 1e-9);
    EXPECT_NEAR(p.p[i].depth, 0.01, 1e-9);
  }
}

// A box resting on a box, both turned a little and A at random about the normal, from 2 cm into
// each other to 2 cm apart: the faces clipped in the reference box's frame give the corners that
// the general clipping (clipFeatures) gives from the faces' world corners, in its order,
// whichever box is the reference and however many corners the overlap has.
TEST(Narrowphase, BoxFacesClippedInTheirFrameAsTheGeneralClipping) {
  uint64_t seed = 17;
  auto uniform = [&] { return unitRandom(seed); };
  auto tilt = [&] {  // 0.5 to 7 degrees about a random axis
    const Vec3 axis(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5);
    return rot((0.5 + 6.5 * uniform()) * M_PI / 180, axis);
  };
  const double margin = 0.02;
  int compared = 0, refA = 0, refB = 0, many = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const Shape a = box(0.05 + uniform(), 0.05 + uniform(), 0.05 + uniform());
    const Shape b = box(0.05 + uniform(), 0.05 + uniform(), 0.05 + uniform());
    const Vec3 hA = a.halfExtents, hB = b.halfExtents;
    const Quat base = rot(2 * M_PI * uniform(), Vec3(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5));
    const Pose pb{Vec3(uniform(), uniform(), uniform()), base * tilt()};
    const Quat spin = rot(2 * M_PI * uniform(), Vec3::UnitY());  // A turned about B's normal
    const Vec3 along = base * Vec3((uniform() - 0.5) * 2 * hB.x(), hB.y() + hA.y() + (uniform() - 0.5) * 0.04,
                                   (uniform() - 0.5) * 2 * hB.z());
    const Pose pa{pb.p + along, base * spin * tilt()};
    Vec3 n;
    if (boxBoxGap(hA, pa, hB, pb, n) > margin) continue;
    ContactPatch ours, theirs;
    if (!boxFacesClipped(hA, pa, hB, pb, n, margin, ours)) continue;  // an edge or a corner
    const Feature fA = supportingFeature(a, pa, -n), fB = supportingFeature(b, pb, n);
    ASSERT_EQ(fA.count, 4) << "trial " << trial;
    ASSERT_EQ(fB.count, 4) << "trial " << trial;
    const auto facing = [&](const Feature& f) {
      return std::abs((f.p[1] - f.p[0]).cross(f.p[2] - f.p[1]).normalized().dot(n));
    };
    const bool refIsB = facing(fB) >= facing(fA);
    clipFeatures(refIsB ? fB : fA, refIsB ? fA : fB, refIsB, n, margin, theirs);
    ++compared;
    ++(refIsB ? refB : refA);
    many += ours.count > 4;
    ASSERT_EQ(ours.count, theirs.count) << "trial " << trial;
    for (int i = 0; i < ours.count; ++i) {  // in the same order: the order the solver takes them in
      EXPECT_LT((ours.p[i].pA - theirs.p[i].pA).norm(), 1e-9) << "trial " << trial << " corner " << i;
      EXPECT_LT((ours.p[i].pB - theirs.p[i].pB).norm(), 1e-9) << "trial " << trial << " corner " << i;
      EXPECT_NEAR(ours.p[i].depth, theirs.p[i].depth, 1e-9) << "trial " << trial << " corner " << i;
      EXPECT_NEAR(ours.p[i].n.dot(n), 1, 1e-12) << "trial " << trial;
    }
  }
  std::printf("box faces compared: %d of 3000 (reference A %d, B %d; more than four corners %d)\n", compared, refA,
              refB, many);
  EXPECT_GT(refA, 500);
  EXPECT_GT(refB, 500);
  EXPECT_GT(many, 500);
}

TEST(Narrowphase, TiltedBoxTouchesWithAnEdgeOrACorner) {
  const double a = 0.3;
  const double low = 0.5 * std::cos(a) + 0.5 * std::sin(a);
  const ContactPatch edge = collide(box(0.5, 0.5, 0.5), Pose{Vec3(0, low - 0.01, 0), rot(a, Vec3::UnitZ())});
  ASSERT_EQ(edge.count, 2);
  expectConsistent(edge);
  EXPECT_NEAR(edge.p[0].depth, 0.01, 1e-6);
  EXPECT_NEAR(std::abs(edge.p[0].pA.z()), 0.5, 1e-6);
  const Quat corner = rot(0.3, Vec3::UnitZ()) * rot(0.4, Vec3::UnitX());
  double lowest = 0;
  for (int i = 0; i < 8; ++i) {
    const Vec3 c((i & 1) ? 0.5 : -0.5, (i & 2) ? 0.5 : -0.5, (i & 4) ? 0.5 : -0.5);
    lowest = std::min(lowest, (corner * c).y());
  }
  const ContactPatch one = collide(box(0.5, 0.5, 0.5), Pose{Vec3(0, -lowest - 0.01, 0), corner});
  ASSERT_EQ(one.count, 1);
  EXPECT_NEAR(one.p[0].depth, 0.01, 1e-6);
}

TEST(Narrowphase, LyingCapsuleGetsBothEnds) {
  // FCL gives one point for capsule-box; clipping the capsule's side line gives both ends.
  const ContactPatch p = collide(capsule(0.2, 0.5), Pose{Vec3(0.1, 0.19, 0.2), rot(M_PI / 2, Vec3::UnitX())});
  ASSERT_EQ(p.count, 2);
  expectConsistent(p);
  EXPECT_NEAR(std::abs(p.p[0].pA.z() - p.p[1].pA.z()), 1.0, 1e-6);
  for (int i = 0; i < 2; ++i) {
    EXPECT_NEAR(p.p[i].depth, 0.01, 1e-6);
    EXPECT_NEAR(p.p[i].pA.y(), -0.01, 1e-6);
  }
  // Standing on one end, it has one point.
  const ContactPatch s = collide(capsule(0.2, 0.5), Pose{Vec3(0, 0.69, 0), rot(0.5, Vec3::UnitX())});
  EXPECT_EQ(s.count, 0);  // 0.5 rad tilt lifts it: lowest point at 0.69 - (0.5 cos 0.5 + 0.2) > 0
  const double y = 0.5 * std::cos(0.5) + 0.2 - 0.01;
  const ContactPatch t = collide(capsule(0.2, 0.5), Pose{Vec3(0, y, 0), rot(0.5, Vec3::UnitX())});
  ASSERT_EQ(t.count, 1);
  EXPECT_NEAR(t.p[0].depth, 0.01, 1e-5);
}

TEST(Narrowphase, SphereAndCylinder) {
  const ContactPatch s = collide(sphere(0.3), Pose{Vec3(1, 0.29, 2), Quat::Identity()});
  ASSERT_EQ(s.count, 1);
  EXPECT_LT((s.p[0].pA - Vec3(1, -0.01, 2)).norm(), 1e-6);
  EXPECT_NEAR(s.p[0].depth, 0.01, 1e-6);
  const ContactPatch side = collide(cylinder(0.2, 0.5), Pose{Vec3(0, 0.19, 0), rot(M_PI / 2, Vec3::UnitZ())});
  EXPECT_EQ(side.count, 2);
  const ContactPatch cap = collide(cylinder(0.2, 0.5), Pose{Vec3(0, 0.49, 0), Quat::Identity()});
  EXPECT_EQ(cap.count, 4);  // the rim's octagon, reduced to four points
  for (int i = 0; i < cap.count; ++i) EXPECT_NEAR(Vec3(cap.p[i].pA.x(), 0, cap.p[i].pA.z()).norm(), 0.2, 1e-9);
}

TEST(Narrowphase, PlaneAndTriangleMeshGiveAFace) {
  Shape plane;
  plane.type = ShapeType::Plane;
  plane.normal = Vec3::UnitY();
  plane.offset = 0;
  const ContactPatch p = collide(box(0.5, 0.5, 0.5), Pose{Vec3(0, 0.49, 0), Quat::Identity()}, plane, Pose{});
  ASSERT_EQ(p.count, 4);
  expectConsistent(p);
  const Shape m = groundMesh();
  const ContactPatch q = collide(box(0.5, 0.5, 0.5), Pose{Vec3(0.2, 0.49, 0.1), Quat::Identity()}, m, Pose{});
  ASSERT_EQ(q.count, 4);
  expectConsistent(q);
  for (int i = 0; i < 4; ++i) {
    EXPECT_LT((q.p[i].n - Vec3::UnitY()).norm(), 1e-9);
    EXPECT_NEAR(q.p[i].depth, 0.01, 1e-9);
  }
}

TEST(Manifold, PointsPersistAcrossStepsAndNewOnesGetNewIds) {
  ManifoldCache cache;
  const Shape b = box(0.5, 0.5, 0.5);
  Pose pose{Vec3(0, 0.49, 0), Quat::Identity()};
  cache.beginStep();
  cache.add(1, 0, pose, kGroundPose, 0.5, 0, collide(b, pose), 1.0);
  ASSERT_EQ(cache.manifolds().size(), 1u);
  uint32_t ids[4];
  for (int i = 0; i < 4; ++i) ids[i] = cache.manifolds()[0].points[i].id;
  cache.manifolds()[0].points[0].lambda = 1.5;
  cache.manifolds()[0].twistImpulse = 0.25;
  cache.manifolds()[0].frictionImpulse = Vec3(0.5, 0, -0.5);
  // A small slide keeps every point; its impulse comes along.
  pose.p.x() += 0.005;
  cache.beginStep();
  cache.add(1, 0, pose, kGroundPose, 0.5, 0, collide(b, pose), 1.0);
  const Manifold& m = cache.manifolds()[0];
  int kept = 0;
  for (int i = 0; i < m.count; ++i)
    for (int k = 0; k < 4; ++k)
      if (m.points[i].id == ids[k]) {
        ++kept;
        EXPECT_EQ(m.points[i].age, 1);
        if (k == 0) {
          EXPECT_EQ(m.points[i].lambda, 1.5);
        }
      }
  EXPECT_EQ(kept, 4);
  EXPECT_EQ(m.twistImpulse, 0.25);
  EXPECT_EQ(m.frictionImpulse, Vec3(0.5, 0, -0.5));
  // A jump of 30 cm: the same corners of the box, but elsewhere on the ground: all points are new.
  pose.p.x() += 0.3;
  cache.beginStep();
  cache.add(1, 0, pose, kGroundPose, 0.5, 0, collide(b, pose), 1.0);
  for (int i = 0; i < cache.manifolds()[0].count; ++i)
    for (int k = 0; k < 4; ++k) EXPECT_NE(cache.manifolds()[0].points[i].id, ids[k]);
}

TEST(Manifold, ReductionKeepsTheDeepestAndTheArea) {
  ContactPatch p;
  for (int i = 0; i < 8; ++i) {
    const double a = i * M_PI / 4;
    p.add(ContactPoint{Vec3(std::cos(a), 0, std::sin(a)), Vec3(std::cos(a), 0.01, std::sin(a)), Vec3::UnitY(), i == 3 ? 0.02 : 0.01});
  }
  reducePatch(p);
  ASSERT_EQ(p.count, 4);
  EXPECT_EQ(p.p[0].depth, 0.02);  // the deepest is kept first
  // The four kept points span the octagon: their quad has area 2 (a square inscribed in the unit circle).
  double area = 0;
  Vec3 c = Vec3::Zero();
  for (int i = 0; i < 4; ++i) c += p.p[i].pA / 4;
  std::vector<std::pair<double, Vec3>> byAngle;
  for (int i = 0; i < 4; ++i) byAngle.push_back({std::atan2(p.p[i].pA.z() - c.z(), p.p[i].pA.x() - c.x()), p.p[i].pA});
  std::sort(byAngle.begin(), byAngle.end(), [](auto& x, auto& y) { return x.first < y.first; });
  for (int i = 0; i < 4; ++i) {
    const Vec3& u = byAngle[static_cast<size_t>(i)].second;
    const Vec3& v = byAngle[static_cast<size_t>((i + 1) % 4)].second;
    area += 0.5 * (u.x() * v.z() - u.z() * v.x());
  }
  EXPECT_NEAR(std::abs(area), 2.0, 1e-9);
}

TEST(Broadphase, FindsOverlapsInOrderAndSkipsJointsAndStatics) {
  Model m;
  auto add = [&](const std::string& n, const Shape& s, bool isStatic) {
    Body b;
    b.name = n;
    b.shape = s;
    b.isStatic = isStatic;
    m.bodies.push_back(b);
  };
  add("ground", kGround, true);
  add("wall", box(0.1, 2, 2), true);
  add("a", box(0.5, 0.5, 0.5), false);
  add("b", box(0.5, 0.5, 0.5), false);
  add("c", box(0.5, 0.5, 0.5), false);
  add("far", sphere(0.5), false);
  Joint j;
  j.bodyA = 3;
  j.bodyB = 4;
  m.joints.push_back(j);
  State s;
  s.bodies.resize(m.bodies.size());
  s.bodies[0].x = kGroundPose.p;
  s.bodies[1].x = Vec3(-0.5, 0, 0);  // overlaps the ground: static-static, skipped
  s.bodies[2].x = Vec3(0, 0.49, 0);
  s.bodies[3].x = Vec3(0.9, 0.49, 0);
  s.bodies[4].x = Vec3(1.8, 0.49, 0);
  s.bodies[5].x = Vec3(0, 10, 0);
  Broadphase bp(m);
  const std::vector<double> still(m.bodies.size(), 0.0);
  std::vector<Vec3> move(m.bodies.size(), Vec3::Zero());
  bp.update(s, still, move, Vec3::Zero());
  std::vector<std::pair<int, int>> pairs;
  EXPECT_TRUE(bp.findPairs(pairs, 100));
  const std::vector<std::pair<int, int>> expected = {{0, 2}, {0, 3}, {0, 4}, {1, 2}, {2, 3}};
  EXPECT_EQ(pairs, expected);
  // Moving a body updates the tree.
  s.bodies[5].x = Vec3(1.8, 1.4, 0);
  bp.update(s, still, move, Vec3::Zero());
  EXPECT_EQ(bp.movedLastUpdate(), 1);
  EXPECT_TRUE(bp.findPairs(pairs, 100));
  EXPECT_TRUE(std::find(pairs.begin(), pairs.end(), std::make_pair(4, 5)) != pairs.end());
  // Nothing moved: the tree is left alone and the pairs are the same.
  const std::vector<std::pair<int, int>> before = pairs;
  bp.update(s, still, move, Vec3::Zero());
  EXPECT_EQ(bp.movedLastUpdate(), 0);
  EXPECT_TRUE(bp.findPairs(pairs, 100));
  EXPECT_EQ(pairs, before);
  // A move inside the fat box keeps the body in place in the tree; its reach box still decides.
  s.bodies[5].x = Vec3(1.8, 1.4 + 1e-4, 0);
  bp.update(s, still, move, Vec3::Zero());
  EXPECT_EQ(bp.movedLastUpdate(), 0);
  // Moving away drops the candidate pair; the step's fall grows the reach box downward only.
  s.bodies[5].x = Vec3(1.8, 10, 0);
  bp.update(s, still, move, Vec3::Zero());
  EXPECT_TRUE(bp.findPairs(pairs, 100));
  EXPECT_TRUE(std::find(pairs.begin(), pairs.end(), std::make_pair(4, 5)) == pairs.end());
  s.bodies[5].x = Vec3(1.8, 1.52, 0);  // 2 cm above b's top (0.99), sphere radius 0.5
  bp.update(s, still, move, Vec3::Zero());
  EXPECT_TRUE(bp.findPairs(pairs, 100));
  EXPECT_TRUE(std::find(pairs.begin(), pairs.end(), std::make_pair(4, 5)) == pairs.end());
  bp.update(s, still, move, Vec3(0, -0.05, 0));
  EXPECT_TRUE(bp.findPairs(pairs, 100));
  EXPECT_TRUE(std::find(pairs.begin(), pairs.end(), std::make_pair(4, 5)) != pairs.end());
  s.bodies[5].x = Vec3(2.83, 0.49, 0);  // 3 cm to the side of c: the fall does not reach sideways
  bp.update(s, still, move, Vec3(0, -0.05, 0));
  EXPECT_TRUE(bp.findPairs(pairs, 100));
  EXPECT_TRUE(std::find(pairs.begin(), pairs.end(), std::make_pair(4, 5)) == pairs.end());
  // The step's move sweeps the box along the velocity only: falling at 3 m/s (5 cm in a step) it
  // still does not reach c 3 cm to its side; moving towards c at 3 m/s it does.
  move[5] = Vec3(0, -0.05, 0);
  bp.update(s, still, move, Vec3(0, -0.003, 0));
  EXPECT_TRUE(bp.findPairs(pairs, 100));
  EXPECT_TRUE(std::find(pairs.begin(), pairs.end(), std::make_pair(4, 5)) == pairs.end());
  move[5] = Vec3(-0.05, 0, 0);
  bp.update(s, still, move, Vec3(0, -0.003, 0));
  EXPECT_TRUE(bp.findPairs(pairs, 100));
  EXPECT_TRUE(std::find(pairs.begin(), pairs.end(), std::make_pair(4, 5)) != pairs.end());
}

// Shapes apart by less than the margin get speculative points (depth < 0): FCL's distance query
// for primitives, the nearest triangle for meshes, the plane itself for planes.
// The moved bodies' queries on a pool's threads, per block of 32, their lists merged: the pairs
// are every overlapping pair, in order, once, on one thread and on three alike. 600 unit boxes
// placed at random (all move in the first update: 19 blocks), checked against every pair by hand.
TEST(Broadphase, QueriesOnThreadsFindEveryPairInOrderOnce) {
  Model m;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> at(0.0, 12.0);
  State s;
  for (int i = 0; i < 600; ++i) addUnitBox(m, s, Vec3(at(rng), at(rng), at(rng)));
  std::vector<std::pair<int, int>> expected;  // unturned unit boxes: their boxes overlap within 1 m on every axis
  for (int i = 0; i < 600; ++i)
    for (int j = i + 1; j < 600; ++j)
      if (((s.bodies[static_cast<size_t>(i)].x - s.bodies[static_cast<size_t>(j)].x).cwiseAbs().array() <= 1.0).all())
        expected.emplace_back(i, j);
  ASSERT_GT(expected.size(), 100u);
  const std::vector<double> still(m.bodies.size(), 0.0);
  const std::vector<Vec3> move(m.bodies.size(), Vec3::Zero());
  WorkerPool three(3);
  for (WorkerPool* pool : {&WorkerPool::callerOnly(), &three}) {
    Broadphase bp(m);
    bp.update(s, still, move, Vec3::Zero());
    ASSERT_EQ(bp.movedLastUpdate(), 600);
    std::vector<std::pair<int, int>> pairs;
    ASSERT_TRUE(bp.findPairs(pairs, 100000, *pool));
    EXPECT_EQ(pairs, expected) << pool->threads() << " threads";
  }
}

// The bodies' boxes, the candidates' reach test and the planes' bodies on a pool's threads, per
// block, taken in block order: with a plane first in the body list and one last (its pairs fall
// among the boxes' in the sorted order, so they are merged in, not appended), the pairs are every
// overlapping pair and every box reaching below a plane, in order, once, on one thread and on three
// alike; and past maxPairs both stop with the pairs the serial loop had found: the candidates' in
// order, then each plane's by body.
TEST(Broadphase, BoxesAndPlanesOnThreadsGiveThePairsInOrder) {
  Model m;
  auto plane = [&](const Vec3& n, double offset) {
    Body b;
    b.name = "plane" + std::to_string(m.bodies.size());
    b.isStatic = true;
    b.shape.type = ShapeType::Plane;
    b.shape.normal = n;
    b.shape.offset = offset;
    m.bodies.push_back(b);
  };
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> at(0.0, 12.0);
  State s;
  plane(Vec3::UnitY(), 0.0);  // body 0: the ground, y = 0
  s.bodies.emplace_back();
  const int boxes = 5000, first = 1;
  for (int i = 0; i < boxes; ++i) addUnitBox(m, s, Vec3(at(rng), at(rng), at(rng)) * 2.0);
  plane(Vec3::UnitX(), 1.0);  // the last body: a wall, x = 1
  s.bodies.emplace_back();
  const int wall = first + boxes;
  std::vector<std::pair<int, int>> boxPairs, groundPairs, wallPairs;
  for (int i = first; i < wall; ++i) {
    const Vec3& xi = s.bodies[static_cast<size_t>(i)].x;
    for (int j = i + 1; j < wall; ++j)
      if (((xi - s.bodies[static_cast<size_t>(j)].x).cwiseAbs().array() <= 1.0).all()) boxPairs.emplace_back(i, j);
    if (xi.y() - 0.5 <= 0.0) groundPairs.emplace_back(0, i);
    if (xi.x() - 0.5 <= 1.0) wallPairs.emplace_back(i, wall);
  }
  ASSERT_GT(boxPairs.size(), 4096u);  // more than one block of candidates
  ASSERT_GT(groundPairs.size(), 10u);
  ASSERT_GT(wallPairs.size(), 10u);
  std::vector<std::pair<int, int>> expected = boxPairs;
  expected.insert(expected.end(), groundPairs.begin(), groundPairs.end());
  expected.insert(expected.end(), wallPairs.begin(), wallPairs.end());
  std::vector<std::pair<int, int>> sorted = expected;
  std::sort(sorted.begin(), sorted.end());
  ASSERT_NE(sorted, expected);  // the wall's pairs do fall among the boxes'
  const std::vector<double> still(m.bodies.size(), 0.0);
  const std::vector<Vec3> move(m.bodies.size(), Vec3::Zero());
  WorkerPool three(3);
  for (WorkerPool* pool : {&WorkerPool::callerOnly(), &three}) {
    Broadphase bp(m);
    bp.update(s, still, move, Vec3::Zero(), *pool);
    ASSERT_EQ(bp.movedLastUpdate(), boxes);
    std::vector<std::pair<int, int>> pairs;
    ASSERT_TRUE(bp.findPairs(pairs, 1000000, *pool));
    EXPECT_EQ(pairs, sorted) << pool->threads() << " threads";
    // Past the cap among the candidates, and among the wall's pairs: the first cap + 1 found.
    for (const size_t cap : {size_t{5000}, expected.size() - 5}) {
      const std::vector<std::pair<int, int>> found(expected.begin(), expected.begin() + static_cast<long>(cap) + 1);
      EXPECT_FALSE(bp.findPairs(pairs, cap, *pool));
      EXPECT_EQ(pairs, found) << pool->threads() << " threads, cap " << cap;
    }
  }
}

// FCL rebuilds its whole tree top down after an update once the tree is ten levels deeper than a
// balanced one: on the settling 100-level pyramid, where a hundred bodies leave their fat boxes
// every other step, that was nearly every update, 1.4 ms on the calling thread (docs/benchmarks.md,
// "The broadphase tree's rebuilds"). Here a 100-level pyramid of 5050 boxes, every other box then
// moved 30 cm (out of its fat box): the tree, more than ten levels too deep, is kept as it is, and
// moving a few more bodies keeps it too; and a tree pushed past the bound is rebuilt.
TEST(Broadphase, MovedBodiesRebuildNoTreeWithinTheBound) {
  Model m;
  State s;
  const int levels = 100;
  for (int level = 0; level < levels; ++level)
    for (int i = 0; i < levels - level; ++i) addUnitBox(m, s, Vec3(1.02 * (i + 0.5 * level), 0.5 + level, 0));
  const int n = static_cast<int>(m.bodies.size());
  // The bound: 2 log2(n) + 10 levels (rounded up) above a balanced tree's log2(n).
  const auto boundFor = [](int leaves) { return std::log2(leaves) + 2 * std::ceil(std::log2(leaves)) + 10; };
  const double balanced = std::log2(n), bound = boundFor(n);
  const std::vector<double> still(m.bodies.size(), 0.0);
  const std::vector<Vec3> move(m.bodies.size(), Vec3::Zero());
  Broadphase bp(m);
  bp.update(s, still, move, Vec3::Zero());
  for (size_t i = 0; i < s.bodies.size(); i += 2) s.bodies[i].x.y() -= 0.3;
  bp.update(s, still, move, Vec3::Zero());
  ASSERT_EQ(bp.movedLastUpdate(), (n + 1) / 2);
  const int kept = bp.treeHeight();
  EXPECT_GT(kept, balanced + 10) << "a tree FCL's own rule rebuilds";
  EXPECT_LE(kept, bound);
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> body(0, n - 1);
  for (int k = 0; k < 3; ++k) s.bodies[static_cast<size_t>(body(rng))].x.z() += 0.5;
  bp.update(s, still, move, Vec3::Zero());
  ASSERT_EQ(bp.movedLastUpdate(), 3);
  EXPECT_GE(bp.treeHeight(), kept - 1);
  // A conveyor: a row of 1000 boxes, the first taken to the end of the row, one each update. Kept
  // as FCL balances it a few nodes at a time, this tree grows over 260 levels deep in 5000
  // updates; it is rebuilt once past the bound.
  Model row;
  State along;
  const int count = 1000;
  for (int i = 0; i < count; ++i) addUnitBox(row, along, Vec3(1.1 * i, 0, 0));
  const std::vector<double> rowStill(row.bodies.size(), 0.0);
  const std::vector<Vec3> rowMove(row.bodies.size(), Vec3::Zero());
  Broadphase conveyor(row);
  conveyor.update(along, rowStill, rowMove, Vec3::Zero());
  int highest = 0;
  for (int k = 0; k < 5 * count; ++k) {
    along.bodies[static_cast<size_t>(k % count)].x.x() += 1.1 * count;
    conveyor.update(along, rowStill, rowMove, Vec3::Zero());
    ASSERT_EQ(conveyor.movedLastUpdate(), 1);
    highest = std::max(highest, conveyor.treeHeight());
  }
  EXPECT_LE(highest, boundFor(count) + 1);
}

TEST(Narrowphase, SpeculativePointsWithinTheMargin) {
  const Shape b = box(0.5, 0.5, 0.5);
  const ContactPatch near = collide(b, Pose{Vec3(0, 0.503, 0), Quat::Identity()});
  ASSERT_EQ(near.count, 4);
  expectConsistent(near);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(near.p[i].depth, -0.003, 1e-9);
  EXPECT_EQ(collide(b, Pose{Vec3(0, 0.51, 0), Quat::Identity()}).count, 0);  // 1 cm: beyond 5 mm
  const ContactPatch wide = collide(b, Pose{Vec3(0, 0.51, 0), Quat::Identity()}, kGround, kGroundPose, 0.02);
  EXPECT_EQ(wide.count, 4);
  const ContactPatch cap = collide(capsule(0.2, 0.5), Pose{Vec3(0, 0.203, 0), rot(M_PI / 2, Vec3::UnitX())});
  ASSERT_EQ(cap.count, 2);
  EXPECT_NEAR(cap.p[0].depth, -0.003, 1e-6);
  Shape plane;
  plane.type = ShapeType::Plane;
  const ContactPatch pl = collide(b, Pose{Vec3(0, 0.503, 0), Quat::Identity()}, plane, Pose{});
  ASSERT_EQ(pl.count, 4);
  EXPECT_NEAR(pl.p[0].depth, -0.003, 1e-12);
  const Shape m = groundMesh();
  const ContactPatch sm = collide(sphere(0.3), Pose{Vec3(0.7, 0.31, 1.2), Quat::Identity()}, m, Pose{}, 0.02);
  ASSERT_EQ(sm.count, 1);
  EXPECT_NEAR(sm.p[0].depth, -0.01, 1e-9);
  EXPECT_LT((sm.p[0].pB - Vec3(0.7, 0, 1.2)).norm(), 1e-9);
}

// Two unit boxes at poses A0, B0 and the manifold of one point between them, for the pair
// cache's tests; moved() is a pose shifted and turned by up to `scale` at random.
struct CachedPair {
  const Pose A0{Vec3(0.1, 0.2, -0.3), Rq(Vec3(0.2, -0.1, 0.4))};
  const Pose B0{Vec3(0.3, 1.1, -0.2), Rq(Vec3(-0.3, 0.2, 0.1))};
  Manifold m;
  uint64_t seed;
  explicit CachedPair(uint64_t s) : seed(s) {
    ManifoldCache cache;
    cache.beginStep();
    ContactPatch p;
    p.add(ContactPoint{Vec3(0, 0.5, 0), Vec3(0, 0.5, 0), Vec3::UnitY(), 0});
    cache.add(0, 1, A0, B0, 0.5, 0, p, box(0.5, 0.5, 0.5).boundingRadius());
    m = cache.manifolds()[0];
  }
  double uniform() { return unitRandom(seed) * 2 - 1; }
  Vec3 random(double scale) { return scale * Vec3(uniform(), uniform(), uniform()); }
  Pose moved(const Pose& P, double scale) {
    const Vec3 dp = random(scale);
    return Pose{P.p + dp, P.q * Rq(random(scale))};
  }
};

// The pair cache's bound: every point fixed on B within the manifold's reach moves, relative to
// A, by no more than pairShift() says, whatever the two bodies did.
TEST(Manifold, PairShiftBoundsTheMotionOfEveryPoint) {
  CachedPair pair(7);
  const Pose &A0 = pair.A0, &B0 = pair.B0;
  for (int trial = 0; trial < 200; ++trial) {
    const double scale = trial < 100 ? 1e-3 : 0.3;  // small moves (the cache's range) and large ones
    const Pose A = pair.moved(A0, scale), B = pair.moved(B0, scale);
    const double bound = pairShift(pair.m, A, B);
    for (int k = 0; k < 20; ++k) {
      // A point of B (inside its bounding sphere), seen from A, then and now.
      const Vec3 x = pair.random(0.5);
      const Vec3 then = A0.unrotate(B0.apply(x) - A0.p), now = A.unrotate(B.apply(x) - A.p);
      EXPECT_LE((now - then).norm(), bound + 1e-12) << "trial " << trial;
    }
  }
}

// pairShiftBelow, the cache's test with tan for the angle first, decides as pairShift() < limit
// does: on moves around the limit (both answers occur) and far beyond it.
TEST(Manifold, PairShiftBelowDecidesAsPairShift) {
  CachedPair pair(11);
  int below = 0, trials = 0;
  for (double scale : {2e-4, 5e-4, 1e-3, 0.5, 3.0}) {
    for (int trial = 0; trial < 200; ++trial, ++trials) {
      const Pose A = pair.moved(pair.A0, scale), B = pair.moved(pair.B0, scale);
      const bool exact = pairShift(pair.m, A, B) < kPairCacheShift;
      EXPECT_EQ(pairShiftBelow(pair.m, A, B, kPairCacheShift), exact) << "scale " << scale << " trial " << trial;
      below += exact;
    }
  }
  EXPECT_GT(below, 50);
  EXPECT_LT(below, trials - 50);
}

// A box at rest keeps its manifold without a narrowphase query; one that moves more than the
// cache's shift gets new points.
TEST(Manifold, ReuseKeepsPointsAndImpulses) {
  ManifoldCache cache;
  const Shape b = box(0.5, 0.5, 0.5);
  Pose pose{Vec3(0, 0.49, 0), Quat::Identity()};
  cache.beginStep();
  cache.add(1, 0, pose, kGroundPose, 0.5, 0, collide(b, pose), b.boundingRadius());
  cache.manifolds()[0].points[2].lambda = 0.75;
  const Manifold first = cache.manifolds()[0];
  pose.p.y() -= 0.0004;  // sinks 0.4 mm: within the cache's 1 mm
  ASSERT_LT(pairShift(first, pose, kGroundPose), kPairCacheShift);
  cache.beginStep();
  const Manifold* old = cache.previous(1, 0);
  ASSERT_NE(old, nullptr);
  cache.reuse(*old);
  const Manifold& m = cache.manifolds()[0];
  ASSERT_EQ(m.count, first.count);
  for (int i = 0; i < m.count; ++i) {
    const ManifoldPoint& p = m.points[i];
    EXPECT_EQ(p.id, first.points[i].id);
    EXPECT_EQ(p.age, first.points[i].age + 1);
    EXPECT_EQ(p.localA, first.points[i].localA);
    EXPECT_EQ(p.localB, first.points[i].localB);
    EXPECT_EQ(p.depth, first.points[i].depth);  // as detected
    // The points fixed on the bodies give the depth at the new pose (what s2's rows measure).
    const double now = -(pose.apply(p.localA) - kGroundPose.apply(p.localB)).dot(kGroundPose.rotate(p.localN));
    EXPECT_NEAR(now, first.points[i].depth + 0.0004, 1e-12);
  }
  EXPECT_EQ(m.points[2].lambda, 0.75);
  // Tipped by 0.2 degrees about a bottom edge: 1.7 mm at the far corners, beyond the cache.
  pose.q = Rq(Vec3(0, 0, 0.0035));
  EXPECT_GT(pairShift(m, pose, kGroundPose), kPairCacheShift);
}

// Threads merge the step's pairs with last step's manifolds a run at a time: a run that starts
// anywhere, at a pair last step had or not, finds what one merge from the first pair finds.
TEST(Manifold, ARunsMergeFromItsStartFindsWhatTheWholeMergeFinds) {
  ManifoldCache cache;
  cache.beginStep();
  for (auto [a, b] : std::vector<std::pair<int, int>>{{1, 0}, {0, 3}, {5, 2}, {2, 6}, {4, 7}, {9, 8}}) {
    Manifold m;
    m.a = a;
    m.b = b;
    cache.take(m);
  }
  cache.beginStep();
  // This step's pairs in key order, as the broadphase gives them: some new, (2, 5) the other way
  // round (a different orientation is not the same manifold), one past the last.
  const std::vector<std::pair<int, int>> pairs{{1, 0}, {0, 2}, {0, 3}, {2, 5}, {2, 6}, {3, 4}, {4, 7}, {9, 8}, {9, 10}};
  std::vector<const Manifold*> whole;
  size_t cursor = 0;
  for (auto [a, b] : pairs) whole.push_back(cache.previous(a, b, cursor));
  ASSERT_NE(whole[0], nullptr);
  EXPECT_EQ(whole[1], nullptr);
  ASSERT_NE(whole[2], nullptr);
  EXPECT_EQ(whole[2]->b, 3);
  EXPECT_EQ(whole[3], nullptr);
  EXPECT_NE(whole[4], nullptr);
  EXPECT_EQ(whole[5], nullptr);
  EXPECT_NE(whole[6], nullptr);
  EXPECT_NE(whole[7], nullptr);
  EXPECT_EQ(whole[8], nullptr);
  for (size_t first = 0; first < pairs.size(); ++first) {
    size_t run = cache.start(pairs[first].first, pairs[first].second);
    for (size_t k = first; k < pairs.size(); ++k)
      EXPECT_EQ(cache.previous(pairs[k].first, pairs[k].second, run), whole[k]) << "run from " << first << ", pair " << k;
  }
}

// The closed forms substep uses before (or instead of) FCL: box-box and round-box pairs further
// apart than the margin are dropped without asking FCL, sphere and capsule pairs get their normal
// and depth from their core segments. Checked against FCL's own answer on random pairs: a pair
// FCL finds within the margin is never dropped, one it finds beyond is never reported, and for
// round pairs the depth is FCL's.
TEST(Narrowphase, ClosedFormsAgreeWithFcl) {
  const Shape shapes[] = {box(0.4, 0.2, 0.3), capsule(0.1, 0.3), sphere(0.25), capsule(0.2, 0.05), box(0.05, 0.5, 0.1)};
  uint64_t seed = 11;
  auto uniform = [&] { return unitRandom(seed) * 2 - 1; };
  const double margin = 0.03;
  int reported = 0, dropped = 0, compared = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const Shape& a = shapes[trial % 5];
    const Shape& b = shapes[(trial / 5) % 5];
    const Pose pa{Vec3(uniform(), uniform(), uniform()) * 0.6, Rq(3 * Vec3(uniform(), uniform(), uniform()))};
    const Pose pb{Vec3(uniform(), uniform(), uniform()) * 0.6, Rq(3 * Vec3(uniform(), uniform(), uniform()))};
    const ContactPatch ours = collide(a, pa, b, pb, margin);
    // FCL's answer: penetration depth when colliding, else the distance (as a negative depth).
    const CollisionShape ca = makeCollisionShape(a), cb = makeCollisionShape(b);
    auto toFcl = [](const Pose& p, const CollisionShape& c) {
      fcl::Transform3d t = fcl::Transform3d::Identity();
      t.linear() = (p.q * c.offset.q).toRotationMatrix();
      t.translation() = p.apply(c.offset.p);
      return t;
    };
    fcl::CollisionRequestd req(1, true);
    req.gjk_solver_type = fcl::GST_LIBCCD;
    fcl::CollisionResultd res;
    fcl::collide(ca.geometry.get(), toFcl(pa, ca), cb.geometry.get(), toFcl(pb, cb), req, res);
    double fclDepth;
    if (res.numContacts() > 0) {
      fclDepth = res.getContact(0).penetration_depth;
    } else {
      fcl::DistanceRequestd dreq(true);
      dreq.gjk_solver_type = fcl::GST_LIBCCD;
      fcl::DistanceResultd dres;
      fcl::distance(ca.geometry.get(), toFcl(pa, ca), cb.geometry.get(), toFcl(pb, cb), dreq, dres);
      fclDepth = -dres.min_distance;
    }
    if (fclDepth > -margin + 1e-4) {
      EXPECT_GT(ours.count, 0) << "trial " << trial << ": FCL depth " << fclDepth << " but no points";
      ++reported;
    } else if (fclDepth < -margin - 1e-4) {
      EXPECT_EQ(ours.count, 0) << "trial " << trial << ": FCL depth " << fclDepth << " but points";
      ++dropped;
    }
    // Separated round pairs: FCL's GJK distance is exact to its tolerance. (Overlapping ones
    // are not compared: libccd's MPR depth is an estimate, off by 2 to 3 % at 10 cm, where the
    // core segments give the exact one. Round shapes against boxes: RoundAgainstBoxMatchesTheReference.)
    const bool round = a.type != ShapeType::Box && b.type != ShapeType::Box;
    if (round && ours.count > 0 && fclDepth < -1e-3) {
      EXPECT_NEAR(deepestDepth(ours), fclDepth, 1e-5) << "trial " << trial;
      expectConsistent(ours);
      ++compared;
    }
  }
  // The random poses cover both sides of the margin and the round pairs.
  EXPECT_GT(reported, 300);
  EXPECT_GT(dropped, 300);
  EXPECT_GT(compared, 20);
}

// An independent reference for a sphere or capsule against a box: the distance from a point to a
// box is exact by clamping in the box's frame, and along the core segment it is a convex function
// of the segment's parameter, so a ternary search finds its minimum (to 1e-12 of the segment).
double coreBoxDistance(const Shape& r, const Pose& pr, const Shape& b, const Pose& pb) {
  const Vec3 half = r.type == ShapeType::Capsule ? pr.rotate(Vec3(0, r.halfHeight, 0)) : Vec3::Zero();
  const Vec3 p0 = pr.p - half, p1 = pr.p + half;
  auto at = [&](double t) {
    const Vec3 local = pb.q.conjugate() * (p0 + t * (p1 - p0) - pb.p);
    return (local - local.cwiseMax(-b.halfExtents).cwiseMin(b.halfExtents)).norm();
  };
  double lo = 0, hi = 1;
  for (int k = 0; k < 100; ++k) {
    const double m1 = lo + (hi - lo) / 3, m2 = hi - (hi - lo) / 3;
    (at(m1) <= at(m2) ? hi : lo) = at(m1) <= at(m2) ? m2 : m1;
  }
  return std::min({at(0), at(1), at(0.5 * (lo + hi))});
}

// Spheres and capsules against boxes in closed form (roundBoxContact), on random pairs from just
// apart to overlapping by the radius and half the box's smallest size. Apart, the gap is the reference distance
// to 1e-9 m; overlapping, moving the round shape out by the depth along the normal leaves the
// pair touching (the reference distance 0 to 1e-9 m). Printed for comparison: how far the
// manifold's deepest point is from the gap (the supporting features clipped along the normal, as
// for every pair: a face supports while within a few degrees of facing the normal, so its corners
// sit off the exact distance) and how far FCL's estimate (libccd's MPR) is.
TEST(Narrowphase, RoundAgainstBoxMatchesTheReference) {
  uint64_t seed = 9;
  auto uniform = [&] { return unitRandom(seed); };
  Narrowphase np, general;
  general.useGeneralPath(true);
  int apart = 0, deepCores = 0, shallow = 0;
  double worstFcl = 0, worstPatch = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Shape r = trial % 3 == 0 ? sphere(0.05 + 0.5 * uniform()) : capsule(0.05 + 0.3 * uniform(), 0.05 + 0.5 * uniform());
    const Shape b = box(0.05 + uniform(), 0.05 + uniform(), 0.05 + uniform());
    const bool roundFirst = trial % 2 == 0;
    const Vec3 dir = Vec3(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5).normalized();
    const Pose pr{Vec3::Zero(), Rq(4 * Vec3(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5))};
    Pose pb{Vec3::Zero(), Rq(4 * Vec3(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5))};
    auto patch = [&](Narrowphase& n) {
      ContactPatch p;
      if (roundFirst) {
        n.collide(r, makeCollisionShape(r), pr, b, makeCollisionShape(b), pb, 0.02, p);
      } else {
        n.collide(b, makeCollisionShape(b), pb, r, makeCollisionShape(r), pr, 0.02, p);
      }
      return p;
    };
    double lo = 0, hi = 4;  // B slid out along dir until the reference says apart
    for (int k = 0; k < 60; ++k) {
      const double mid = 0.5 * (lo + hi);
      pb.p = mid * dir;
      (coreBoxDistance(r, pr, b, pb) < r.radius ? lo : hi) = mid;
    }
    pb.p = (lo + (trial % 5 == 0 ? 0.015 : -(r.radius + 0.5 * b.halfExtents.minCoeff())) * uniform()) * dir;
    Vec3 n, onBox;
    double gap;
    ASSERT_TRUE(roundBoxContact(r, pr, b, pb, 0.02, n, gap, onBox)) << "trial " << trial;
    EXPECT_NEAR(n.norm(), 1, 1e-12);
    const ContactPatch ours = patch(np);
    ASSERT_GT(ours.count, 0) << "trial " << trial;
    expectConsistent(ours);
    worstPatch = std::max(worstPatch, std::abs(deepestDepth(ours) + gap));
    if (gap > 0) {
      EXPECT_NEAR(gap, coreBoxDistance(r, pr, b, pb) - r.radius, 1e-9) << "trial " << trial;
      ++apart;
      continue;
    }
    (-gap > r.radius ? deepCores : shallow) += 1;  // deeper than the radius: the core reaches in
    const Pose moved{pr.p - gap * n, pr.q};
    const double after = coreBoxDistance(r, moved, b, pb) - r.radius;
    EXPECT_GT(after, -1e-9) << "trial " << trial << " depth " << -gap;
    EXPECT_LT(after, 1e-9) << "trial " << trial << " depth " << -gap;
    worstFcl = std::max(worstFcl, std::abs(deepestDepth(patch(general)) + gap) / -gap);
  }
  std::printf("round shapes against boxes: %d apart, %d overlapping with the core outside, %d with it inside;"
              " manifolds' deepest point up to %.1f mm from the gap; FCL's depth up to %.0f %% off\n",
              apart, shallow, deepCores, worstPatch * 1e3, worstFcl * 100);
  EXPECT_GT(apart, 200);
  EXPECT_GT(shallow, 500);
  EXPECT_GT(deepCores, 100);
}

// Overlapping boxes: the separating-axis fast path against the general path (FCL's collide, then
// the same clipping), on random pairs of random sizes that overlap by up to a fifth of their
// size. Ours takes the axis of least overlap among the 15, the exact penetration depth: moving A
// out by it along our normal leaves the pair touching (checked with FCL), and along FCL's normal
// the boxes overlap at least as much. Where FCL finds the same normal (face contacts, nine pairs
// in ten) the two manifolds are the same points with the same depths to 1e-9 m, in any order.
// (FCL's own depth number, libccd's MPR estimate, was up to 2.6 % below the exact one here.)
TEST(Narrowphase, OverlappingBoxesAgreeWithFcl) {
  uint64_t seed = 5;
  auto uniform = [&] { return unitRandom(seed); };
  Narrowphase fast, general;
  general.useGeneralPath(true);
  int overlapping = 0, same = 0;
  double worstAngle = 0, worstDepth = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Shape a = box(0.05 + uniform(), 0.05 + uniform(), 0.05 + uniform());
    const Shape b = box(0.05 + uniform(), 0.05 + uniform(), 0.05 + uniform());
    const Vec3 dir = Vec3(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5).normalized();
    const Pose pa{Vec3::Zero(), Rq(4 * Vec3(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5))};
    Pose pb{Vec3::Zero(), trial % 4 == 0 ? pa.q : Rq(4 * Vec3(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5))};
    // Slide B out along dir until the pair is about to separate, then back in by up to 20 %.
    double lo = 0, hi = 4;
    for (int k = 0; k < 50; ++k) {
      const double mid = 0.5 * (lo + hi);
      pb.p = mid * dir;
      ContactPatch probe;
      fast.collide(a, makeCollisionShape(a), pa, b, makeCollisionShape(b), pb, 0.0, probe);
      bool deep = false;
      for (int i = 0; i < probe.count; ++i) deep = deep || probe.p[i].depth > 0;
      (deep ? lo : hi) = mid;
    }
    const double size = std::min(a.halfExtents.minCoeff(), b.halfExtents.minCoeff());
    pb.p = (lo - 0.4 * size * uniform()) * dir;
    ContactPatch ours, theirs;
    fast.collide(a, makeCollisionShape(a), pa, b, makeCollisionShape(b), pb, 0.01, ours);
    general.collide(a, makeCollisionShape(a), pa, b, makeCollisionShape(b), pb, 0.01, theirs);
    ASSERT_GT(theirs.count, 0) << "trial " << trial;
    ASSERT_GT(ours.count, 0) << "trial " << trial;
    expectConsistent(ours);
    if (deepestDepth(theirs) <= 1e-6) continue;  // only touching
    ++overlapping;
    // The separating axes' depth: the least overlap over all directions, so along FCL's normal
    // the boxes overlap at least as much (the projections of the two boxes on it, measured here).
    Vec3 axis;
    const double depth = -boxBoxGap(a.halfExtents, pa, b.halfExtents, pb, axis);
    EXPECT_NEAR(axis.dot(ours.p[0].n), 1, 1e-12) << "trial " << trial;
    {
      const Vec3 L = theirs.p[0].n;
      const Mat3 RA = pa.q.toRotationMatrix(), RB = pb.q.toRotationMatrix();
      double reach = 0;
      for (int i = 0; i < 3; ++i)
        reach += a.halfExtents[i] * std::abs(L.dot(RA.col(i))) + b.halfExtents[i] * std::abs(L.dot(RB.col(i)));
      EXPECT_GE(reach - std::abs(L.dot(pb.p - pa.p)), depth - 1e-9) << "trial " << trial;
    }
    // And it is a separating translation: A moved out by it along our normal touches B, FCL says.
    {
      const Pose moved{pa.p + (depth + 1e-7) * axis, pa.q};
      fcl::CollisionRequestd req(1, true);
      fcl::CollisionResultd res;
      auto tf = [](const Pose& p) {
        fcl::Transform3d t = fcl::Transform3d::Identity();
        t.linear() = p.q.toRotationMatrix();
        t.translation() = p.p;
        return t;
      };
      fcl::collide(makeCollisionShape(a).geometry.get(), tf(moved), makeCollisionShape(b).geometry.get(), tf(pb), req, res);
      if (res.numContacts() > 0) {
        EXPECT_LT(res.getContact(0).penetration_depth, 1e-6) << "trial " << trial;
      }
    }
    const double angle = std::acos(std::min(1.0, ours.p[0].n.dot(theirs.p[0].n)));
    if (angle > 1e-6) {  // mostly edge contacts, where FCL's normal is an estimate
      worstAngle = std::max(worstAngle, angle);
      worstDepth = std::max(worstDepth, deepestDepth(theirs) - deepestDepth(ours));
      continue;
    }
    ++same;
    ASSERT_EQ(ours.count, theirs.count) << "trial " << trial;
    for (int i = 0; i < ours.count; ++i) {
      int match = -1;
      for (int j = 0; j < theirs.count; ++j)
        if ((ours.p[i].pA - theirs.p[j].pA).norm() < 1e-9) match = j;
      ASSERT_GE(match, 0) << "trial " << trial << ": our point " << i << " is not one of FCL's path";
      EXPECT_NEAR(ours.p[i].depth, theirs.p[match].depth, 1e-9) << "trial " << trial << " point " << i;
    }
  }
  std::printf("overlapping box pairs: %d, the same normal as FCL's: %d; elsewhere FCL's normal up to %.1f degrees off,"
              " its depth up to %.2f mm deeper\n", overlapping, same, worstAngle * 180 / M_PI, worstDepth * 1e3);
  EXPECT_GT(overlapping, 1500);
  EXPECT_GT(same, overlapping * 9 / 10);
}

// Boxes apart: the fast path stops at the first axis that puts them beyond the margin (a
// pyramid's neighbours in a row). That must not change which pairs get points: on random pairs
// of random sizes and turns, from overlapping to 3 cm apart, the pair has points exactly when
// the full bound over the 15 axes is within the margin, along that bound's axis.
TEST(Narrowphase, BoxesBeyondTheMarginByTheirFullBoundGetNoPoints) {
  uint64_t seed = 11;
  auto uniform = [&] { return unitRandom(seed); };
  Narrowphase fast;
  const double margin = 0.01;
  int withPoints = 0, without = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    const Shape a = box(0.05 + uniform(), 0.05 + uniform(), 0.05 + uniform());
    const Shape b = box(0.05 + uniform(), 0.05 + uniform(), 0.05 + uniform());
    const Vec3 dir = Vec3(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5).normalized();
    const Pose pa{Vec3(uniform(), uniform(), uniform()), Rq(4 * Vec3(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5))};
    Pose pb{pa.p, trial % 3 == 0 ? pa.q : Rq(4 * Vec3(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5))};
    // Out along dir until the full bound says 0 to 3 cm apart (or a little overlapping).
    const double want = -0.005 + 0.035 * uniform();
    double lo = 0, hi = 4;
    Vec3 axis;
    for (int k = 0; k < 60; ++k) {
      const double mid = 0.5 * (lo + hi);
      pb.p = pa.p + mid * dir;
      (boxBoxGap(a.halfExtents, pa, b.halfExtents, pb, axis) < want ? lo : hi) = mid;
    }
    pb.p = pa.p + hi * dir;
    const double gap = boxBoxGap(a.halfExtents, pa, b.halfExtents, pb, axis);
    ContactPatch patch;
    fast.collide(a, makeCollisionShape(a), pa, b, makeCollisionShape(b), pb, margin, patch);
    if (gap > margin) {
      EXPECT_EQ(patch.count, 0) << "trial " << trial << ": gap " << gap;
      ++without;
      continue;
    }
    ASSERT_GT(patch.count, 0) << "trial " << trial << ": gap " << gap;
    EXPECT_NEAR(patch.p[0].n.dot(axis), 1, 1e-12) << "trial " << trial;
    ++withPoints;
  }
  EXPECT_GT(withPoints, 1000);
  EXPECT_GT(without, 1000);
}

// Rays against every shape in closed form (the server's picking), checked against the distances
// that geometry gives, from outside, from inside, and past a body.
TEST(Raycast, EveryShapeAtItsKnownDistance) {
  const Scene s = parseScene(R"({"bodies": [
      {"name": "ground", "static": true, "shape": {"type": "plane"}},
      {"name": "ball", "shape": {"type": "sphere", "radius": 0.5}, "position": [0, 2, 0]},
      {"name": "box", "shape": {"type": "box", "half_extents": [0.5, 0.25, 0.5]}, "position": [3, 2, 0],
       "orientation": [0.92387953, 0, 0.38268343, 0]},
      {"name": "capsule", "shape": {"type": "capsule", "radius": 0.25, "half_height": 0.5}, "position": [6, 2, 0]},
      {"name": "cylinder", "shape": {"type": "cylinder", "radius": 0.25, "half_height": 0.5}, "position": [9, 2, 0]},
      {"name": "gem", "shape": {"type": "convex", "file": "../meshes/gem.obj"}, "position": [12, 2, 0]}]})",
                             "<rays>", SUBSTEP_SOURCE_DIR "/assets/scenes");
  const Model& m = s.model;
  const State& st = s.initial;
  auto down = [&](double x) { return raycast(m, st, Vec3(x, 10, 0), Vec3(0, -1, 0), 100); };
  RayHit h = down(0);
  EXPECT_EQ(h.body, 1);
  EXPECT_NEAR(h.distance, 10 - 2.5, 1e-12);
  EXPECT_NEAR(h.normal.y(), 1, 1e-12);
  h = down(3);  // a box turned about Y: its top face still at y = 2.25
  EXPECT_EQ(h.body, 2);
  EXPECT_NEAR(h.distance, 10 - 2.25, 1e-9);
  h = down(6);  // the capsule stands along Y: its top hemisphere at 2 + 0.5 + 0.25
  EXPECT_EQ(h.body, 3);
  EXPECT_NEAR(h.distance, 10 - 2.75, 1e-12);
  h = down(6.2);  // off its axis, the hemisphere lower: sqrt(0.25² - 0.2²) = 0.15 above the segment
  EXPECT_NEAR(h.distance, 10 - 2.65, 1e-12);
  h = down(9.2);  // a cylinder's flat cap
  EXPECT_EQ(h.body, 4);
  EXPECT_NEAR(h.distance, 10 - 2.5, 1e-12);
  h = down(12);
  EXPECT_EQ(h.body, 5);
  h = down(20);  // nothing but the ground plane
  EXPECT_EQ(h.body, 0);
  EXPECT_NEAR(h.distance, 10, 1e-12);
  EXPECT_EQ(raycast(m, st, Vec3(20, 10, 0), Vec3(0, -1, 0), 100, true).body, -1);  // dynamic bodies only
  EXPECT_EQ(raycast(m, st, Vec3(0, 10, 0), Vec3(0, 1, 0), 100).body, -1);          // pointing away
  EXPECT_EQ(raycast(m, st, Vec3(0, 10, 0), Vec3(0, -1, 0), 5).body, -1);           // too far
  h = raycast(m, st, Vec3(0, 2, 0), Vec3(1, 0, 0), 100);  // from inside the ball
  EXPECT_EQ(h.body, 1);
  EXPECT_EQ(h.distance, 0);
  // Sideways into the capsule's side.
  h = raycast(m, st, Vec3(6, 2.3, -5), Vec3(0, 0, 1), 100);
  EXPECT_EQ(h.body, 3);
  EXPECT_NEAR(h.distance, 5 - 0.25, 1e-12);
  EXPECT_NEAR(h.normal.z(), -1, 1e-12);
}
