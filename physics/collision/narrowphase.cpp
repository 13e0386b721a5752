#include "physics/collision/narrowphase.h"

#include "physics/collision/contact_margin.h"

#include <fcl/narrowphase/collision.h>
#include <fcl/narrowphase/distance.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace substep {

namespace {

// Below this distance two shapes are touching, not apart [m].
constexpr double kTouching = 1e-5;

fcl::Transform3d toFcl(const Pose& p) {
  fcl::Transform3d t = fcl::Transform3d::Identity();
  t.linear() = p.q.toRotationMatrix();
  t.translation() = p.p;
  return t;
}

Pose compose(const Pose& a, const Pose& b) { return Pose{a.apply(b.p), a.q * b.q}; }

// Two boxes seen from A: A's rotation RA, B's rotation RB, and B's turn R = RAᵀRB and centre
// t = RAᵀ(pB − pA) in A's frame. The separating axes and the clipping of two faces take their
// numbers from these nine products once, not from quaternion rotations of every axis and corner.
struct BoxPair {
  Mat3 RA, RB, R;
  Vec3 t;
  BoxPair(const Pose& A, const Pose& B)
      : RA(A.q.toRotationMatrix()), RB(B.q.toRotationMatrix()), R(RA.transpose() * RB), t(RA.transpose() * (B.p - A.p)) {}
};

// A lower bound on the distance between two boxes: the largest gap along the 15 separating axes
// (the faces of each box and the cross products of their edges), in A's frame. Positive only if
// they are apart. Cheap next to FCL's collide-then-distance, which every neighbour pair within the
// broadphase's reach (the 1 cm gaps of a pyramid row) would otherwise pay each step.
// axisA, if given, receives the best axis in A's frame (pointing from B to A) and isFace whether it
// is a face normal rather than the cross product of two edges.
// With stopAbove, it stops once an axis puts them further apart than that: the bound is the
// largest gap over the axes, so it would be above it too, and the caller only asks whether it is
// (a pyramid's neighbours in a row, a centimetre apart, are told by their first axis).
double boxGapLowerBound(const Vec3& hA, const Vec3& hB, const BoxPair& g, Vec3* axisA = nullptr, bool* isFace = nullptr,
                        double stopAbove = std::numeric_limits<double>::infinity()) {
  const Mat3& R = g.R;
  const Vec3& t = g.t;
  double best = -std::numeric_limits<double>::infinity();
  Vec3 bestAxis = Vec3::Zero();
  bool bestFace = true;
  // Axis L (unit, A's frame), B's centre at `along` on it: the gap between the boxes' projections.
  const auto take = [&](double gap, const Vec3& L, double along, bool face) {
    best = gap;
    bestAxis = along > 0 ? Vec3(-L) : L;
    bestFace = face;
  };
  for (int i = 0; i < 3 && !(best > stopAbove); ++i) {  // A's faces
    const double gap = std::abs(t[i]) - (hA[i] + hB.x() * std::abs(R(i, 0)) + hB.y() * std::abs(R(i, 1)) +
                                         hB.z() * std::abs(R(i, 2)));
    if (gap > best) take(gap, Vec3::Unit(i), t[i], true);
  }
  for (int j = 0; j < 3 && !(best > stopAbove); ++j) {  // B's faces
    const double along = R.col(j).dot(t);
    const double gap = std::abs(along) - (hA.x() * std::abs(R(0, j)) + hA.y() * std::abs(R(1, j)) +
                                          hA.z() * std::abs(R(2, j)) + hB[j]);
    if (gap > best) take(gap, R.col(j), along, true);
  }
  for (int i = 0; i < 3 && !(best > stopAbove); ++i)
    for (int j = 0; j < 3; ++j) {
      // A's edge i across B's edge j: L = e_i × b_j in A's frame, b_j = R's column j. Its
      // components, its product with t and with each edge of B follow from R's entries (B's edges
      // are orthonormal: e_i·(b_j × b_m) is R's entry i of the third column, with its sign).
      // Parallel edges: the face axes cover them. An edge axis wins only by a clear margin, so
      // that a face contact (boxes stacked with a tiny turn) keeps its face normal.
      const int i1 = (i + 1) % 3, i2 = (i + 2) % 3, j1 = (j + 1) % 3, j2 = (j + 2) % 3;
      const double n = std::sqrt(R(i1, j) * R(i1, j) + R(i2, j) * R(i2, j));
      if (!(n > 1e-6)) continue;
      const double along = (R(i1, j) * t[i2] - R(i2, j) * t[i1]) / n;
      const double reach = (hA[i1] * std::abs(R(i2, j)) + hA[i2] * std::abs(R(i1, j)) +
                            hB[j1] * std::abs(R(i, j2)) + hB[j2] * std::abs(R(i, j1))) / n;
      const double gap = std::abs(along) - reach;
      if (gap >= best + 1e-9) {
        Vec3 u = Vec3::Zero();
        u[i1] = -R(i2, j) / n;
        u[i2] = R(i1, j) / n;
        take(gap, u, along, false);
      }
    }
  if (axisA) *axisA = bestAxis;
  if (isFace) *isFace = bestFace;
  return best;
}

// The face of a box that the unit direction d (in the box's frame) meets within kFeatureAngle, as
// supportingFeature picks it: its axis, or -1 where d meets an edge or a corner.
int faceAxis(const Vec3& d) {
  const double across = std::sin(kFeatureAngle);
  int axis = -1, free = 0;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d[i]) <= across) ++free;
    else axis = i;
  }
  return free == 2 ? axis : -1;
}

bool isRound(ShapeType t) { return t == ShapeType::Sphere || t == ShapeType::Capsule; }

// The segment a sphere or capsule is the radius-neighbourhood of (a sphere's is a point).
void coreSegment(const Shape& s, const Pose& pose, Vec3& p0, Vec3& p1) {
  const Vec3 half = s.type == ShapeType::Capsule ? pose.rotate(Vec3(0, s.halfHeight, 0)) : Vec3::Zero();
  p0 = pose.p - half;
  p1 = pose.p + half;
}

// A lower bound on the distance between a sphere or capsule and a box: the largest gap along the
// box's face axes and the axes across the capsule's segment and each box edge.
// axis, if given, receives the best axis, pointing from the box towards the round shape.
double roundBoxGapLowerBound(const Shape& round, const Pose& poseR, const Vec3& h, const Pose& poseBox,
                             Vec3* axisOut = nullptr) {
  Vec3 p0, p1;
  coreSegment(round, poseR, p0, p1);
  const Mat3 R = poseBox.q.toRotationMatrix();
  const Vec3 seg = p1 - p0;
  double best = -std::numeric_limits<double>::infinity();
  auto axis = [&](const Vec3& L) {
    const double a = L.dot(p0), b = L.dot(p1), c = L.dot(poseBox.p);
    const double reach = h.x() * std::abs(L.dot(R.col(0))) + h.y() * std::abs(L.dot(R.col(1))) +
                         h.z() * std::abs(L.dot(R.col(2)));
    const double above = std::min(a, b) - round.radius - (c + reach);  // the round shape on L's side
    const double below = (c - reach) - (std::max(a, b) + round.radius);
    if (std::max(above, below) > best) {
      best = std::max(above, below);
      if (axisOut) *axisOut = above >= below ? L : Vec3(-L);
    }
  };
  for (int i = 0; i < 3; ++i) axis(R.col(i));
  for (int i = 0; i < 3; ++i) {
    const Vec3 L = seg.cross(R.col(i));
    const double n = L.norm();
    if (n > 1e-9) axis(L / n);
  }
  return best;
}

// Closest points of segments [p0,p1] and [q0,q1] (clamped parameters).
void closestPointsOfSegments(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1, Vec3& cp, Vec3& cq) {
  const Vec3 d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  double s = 0, t = 0;
  if (a <= 1e-18 && e <= 1e-18) {
    cp = p0;
    cq = q0;
    return;
  }
  if (a <= 1e-18) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= 1e-18) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2), denom = a * e - b * b;
      s = denom > 1e-18 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0) {
        t = 0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1) {
        t = 1;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  cp = p0 + s * d1;
  cq = q0 + t * d2;
}

// Distance from segment [p0,p1] to a box (half extents h) that the segment does not cross, with
// the closest points. The closest pair has an end of the segment or an edge of the box in it
// (a face's interior closest to the segment's interior means the segment is parallel to the
// face, and then an end is as close), so the ends against the box and the segment against the
// twelve edges cover every case.
double segmentBoxDistance(const Vec3& p0, const Vec3& p1, const Vec3& h, const Pose& box, Vec3& onSeg, Vec3& onBox) {
  const Mat3 R = box.q.toRotationMatrix();
  double best = std::numeric_limits<double>::infinity();
  auto consider = [&](const Vec3& s, const Vec3& b) {
    const double d = (s - b).norm();
    if (d < best) best = d, onSeg = s, onBox = b;
  };
  for (const Vec3* e : {&p0, &p1}) {
    const Vec3 local = R.transpose() * (*e - box.p);
    consider(*e, box.p + R * local.cwiseMax(-h).cwiseMin(h));
  }
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    for (int corner = 0; corner < 4; ++corner) {
      Vec3 a = Vec3::Zero();
      a[u] = corner & 1 ? h[u] : -h[u];
      a[v] = corner & 2 ? h[v] : -h[v];
      Vec3 b = a;
      a[axis] = -h[axis];
      b[axis] = h[axis];
      Vec3 cs, cb;
      closestPointsOfSegments(p0, p1, box.apply(a), box.apply(b), cs, cb);
      consider(cs, cb);
    }
  }
  return best;
}

// Sutherland-Hodgman: keeps the part of polygon `in` with (p - o)·m <= 0.
int clipPolygon(const Vec3* in, int n, const Vec3& o, const Vec3& m, Vec3* out, int cap) {
  int k = 0;
  for (int i = 0; i < n; ++i) {
    const Vec3& a = in[i];
    const Vec3& b = in[(i + 1) % n];
    const double da = (a - o).dot(m), db = (b - o).dot(m);
    if (da <= 0 && k < cap) out[k++] = a;
    if ((da < 0 && db > 0) || (da > 0 && db < 0)) {
      if (k < cap) out[k++] = a + (da / (da - db)) * (b - a);
    }
  }
  return k;
}

// Clips segment [a,b] to (p - o)·m <= 0; false if nothing is left.
bool clipSegment(Vec3& a, Vec3& b, const Vec3& o, const Vec3& m) {
  const double da = (a - o).dot(m), db = (b - o).dot(m);
  if (da > 0 && db > 0) return false;
  if (da > 0) a = a + (da / (da - db)) * (b - a);
  else if (db > 0) b = b + (db / (db - da)) * (a - b);
  return true;
}

Vec3 polygonNormal(const Feature& f) {  // Newell's method
  Vec3 n = Vec3::Zero();
  for (int i = 0; i < f.count; ++i) {
    const Vec3& a = f.p[i];
    const Vec3& b = f.p[(i + 1) % f.count];
    n += Vec3((a.y() - b.y()) * (a.z() + b.z()), (a.z() - b.z()) * (a.x() + b.x()), (a.x() - b.x()) * (a.y() + b.y()));
  }
  return n;
}

void addClipped(const Vec3& p, const Vec3& r0, const Vec3& nR, const Vec3& dirI, bool refIsB, const Vec3& n,
                double margin, ContactPatch& out) {
  const double den = dirI.dot(nR);
  if (den < 0.1) return;  // reference face nearly along the normal: no meaningful projection
  const double s = (p - r0).dot(nR) / den;  // separation along the normal
  if (s > margin) return;
  const Vec3 q = p - s * dirI;
  ContactPoint c;
  c.n = n;
  c.depth = -s;
  c.pA = refIsB ? p : q;
  c.pB = refIsB ? q : p;
  out.add(c);
}

double quadArea(const double (*p)[2], int a, int b, int c, int d) {
  auto shoelace = [&](int i, int j, int k, int l) {
    const int v[4] = {i, j, k, l};
    double s = 0;
    for (int m = 0; m < 4; ++m) {
      const double* u = p[v[m]];
      const double* w = p[v[(m + 1) % 4]];
      s += u[0] * w[1] - u[1] * w[0];
    }
    return std::abs(s);
  };
  return std::max({shoelace(a, b, c, d), shoelace(a, b, d, c), shoelace(a, c, b, d)});
}

bool insideTriangle(const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c, double eps) {
  const Vec3 n = (b - a).cross(c - a);
  const double nn = n.squaredNorm();
  if (nn <= 0) return false;
  const double u = (c - b).cross(q - b).dot(n) / nn;
  const double v = (a - c).cross(q - c).dot(n) / nn;
  const double w = 1 - u - v;
  return u >= -eps && v >= -eps && w >= -eps;
}

}  // namespace

void clipFeatures(const Feature& ref, const Feature& inc, bool refIsB, const Vec3& n, double margin,
                  ContactPatch& out) {
  const Vec3 dirI = refIsB ? n : Vec3(-n);  // from the reference towards the incident body
  if (ref.count >= 3) {
    Vec3 nR = polygonNormal(ref);
    if (nR.squaredNorm() < 1e-24) return;
    nR.normalize();
    if (nR.dot(dirI) < 0) nR = -nR;
    Vec3 centroid = Vec3::Zero();
    for (int i = 0; i < ref.count; ++i) centroid += ref.p[i];
    centroid /= ref.count;
    if (inc.count >= 3) {
      Vec3 bufA[2 * kMaxFeaturePoints + 8], bufB[2 * kMaxFeaturePoints + 8];
      const int cap = 2 * kMaxFeaturePoints + 8;
      int k = inc.count;
      std::copy(inc.p, inc.p + k, bufA);
      Vec3* cur = bufA;
      Vec3* nxt = bufB;
      for (int i = 0; i < ref.count && k > 0; ++i) {
        const Vec3& a = ref.p[i];
        const Vec3& b = ref.p[(i + 1) % ref.count];
        Vec3 m = (b - a).cross(nR);
        if ((centroid - a).dot(m) > 0) m = -m;
        k = clipPolygon(cur, k, a, m, nxt, cap);
        std::swap(cur, nxt);
      }
      for (int i = 0; i < k; ++i) addClipped(cur[i], ref.p[0], nR, dirI, refIsB, n, margin, out);
    } else if (inc.count == 2) {
      Vec3 a = inc.p[0], b = inc.p[1];
      for (int i = 0; i < ref.count; ++i) {
        const Vec3& r0 = ref.p[i];
        const Vec3& r1 = ref.p[(i + 1) % ref.count];
        Vec3 m = (r1 - r0).cross(nR);
        if ((centroid - r0).dot(m) > 0) m = -m;
        if (!clipSegment(a, b, r0, m)) return;
      }
      addClipped(a, ref.p[0], nR, dirI, refIsB, n, margin, out);
      if ((b - a).squaredNorm() > 1e-12) addClipped(b, ref.p[0], nR, dirI, refIsB, n, margin, out);
    }
    return;
  }
  if (ref.count == 2 && inc.count == 2) {
    const Vec3 dR = (ref.p[1] - ref.p[0]).normalized();
    const Vec3 dI = (inc.p[1] - inc.p[0]).normalized();
    if (dR.cross(dI).norm() < 0.05) {
      // Parallel edges (a capsule lying along a box edge, two lying capsules): the overlap.
      Vec3 a = inc.p[0], b = inc.p[1];
      if (!clipSegment(a, b, ref.p[0], -dR) || !clipSegment(a, b, ref.p[1], dR)) return;
      Vec3 nR = dirI - dirI.dot(dR) * dR;
      if (nR.squaredNorm() < 1e-12) return;
      nR.normalize();
      addClipped(a, ref.p[0], nR, dirI, refIsB, n, margin, out);
      if ((b - a).squaredNorm() > 1e-12) addClipped(b, ref.p[0], nR, dirI, refIsB, n, margin, out);
    } else {
      Vec3 cr, ci;
      closestPointsOfSegments(ref.p[0], ref.p[1], inc.p[0], inc.p[1], cr, ci);
      ContactPoint c;
      c.n = n;
      c.pA = refIsB ? ci : cr;
      c.pB = refIsB ? cr : ci;
      c.depth = (c.pB - c.pA).dot(n);
      if (c.depth >= -margin) out.add(c);
    }
  }
}

void reducePatch(ContactPatch& patch, int maxPoints) {
  if (patch.count <= maxPoints) return;
  const int n = patch.count;
  Vec3 t1, t2;
  tangentBasis(patch.p[0].n, t1, t2);
  double p2[kMaxPatchPoints][2];
  for (int i = 0; i < n; ++i) {
    p2[i][0] = patch.p[i].pA.dot(t1);
    p2[i][1] = patch.p[i].pA.dot(t2);
  }
  int keep[4] = {0, -1, -1, -1};
  for (int i = 1; i < n; ++i)
    if (patch.p[i].depth > patch.p[keep[0]].depth) keep[0] = i;
  auto d2 = [&](int i, int j) {
    const double dx = p2[i][0] - p2[j][0], dy = p2[i][1] - p2[j][1];
    return dx * dx + dy * dy;
  };
  double best = -1;
  for (int i = 0; i < n; ++i)
    if (d2(i, keep[0]) > best) best = d2(i, keep[0]), keep[1] = i;
  best = -1;
  for (int i = 0; i < n; ++i) {
    if (i == keep[0] || i == keep[1]) continue;
    const double area = std::abs((p2[keep[1]][0] - p2[keep[0]][0]) * (p2[i][1] - p2[keep[0]][1]) -
                                 (p2[keep[1]][1] - p2[keep[0]][1]) * (p2[i][0] - p2[keep[0]][0]));
    if (area > best) best = area, keep[2] = i;
  }
  best = -1;
  for (int i = 0; i < n && maxPoints > 3; ++i) {
    if (i == keep[0] || i == keep[1] || i == keep[2]) continue;
    const double area = quadArea(p2, keep[0], keep[1], keep[2], i);
    if (area > best) best = area, keep[3] = i;
  }
  ContactPoint kept[4];
  int k = 0;
  for (int i = 0; i < std::min(maxPoints, 4); ++i)
    if (keep[i] >= 0) kept[k++] = patch.p[keep[i]];
  patch.count = k;
  std::copy(kept, kept + k, patch.p);
}

Narrowphase::Narrowphase() : request_(4, true), distanceRequest_(true) {
  request_.gjk_solver_type = fcl::GST_LIBCCD;
  distanceRequest_.gjk_solver_type = fcl::GST_LIBCCD;
}

namespace {

// A against one triangle of a static mesh: A's feature clipped to the triangle, along the
// triangle's own normal turned towards A (FCL's mesh normals are unreliable).
void againstTriangle(const Shape& sA, const Pose& poseA, const Mesh& m, const Pose& poseB, intptr_t tri, double margin,
                     ContactPatch& out) {
  if (tri < 0 || tri >= static_cast<intptr_t>(m.triangles.size())) return;
  Feature t;
  t.count = 3;
  for (int k = 0; k < 3; ++k) t.p[k] = poseB.apply(m.vertices[static_cast<size_t>(m.triangles[static_cast<size_t>(tri)][k])]);
  Vec3 nt = (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]);
  if (nt.squaredNorm() < 1e-24) return;
  nt.normalize();
  if (nt.dot(poseA.p - t.p[0]) < 0) nt = -nt;
  const Feature fa = supportingFeature(sA, poseA, -nt);
  ContactPatch tmp;
  if (fa.count == 1) {
    const double s = (fa.p[0] - t.p[0]).dot(nt);
    const Vec3 q = fa.p[0] - s * nt;
    if (s <= margin && insideTriangle(q, t.p[0], t.p[1], t.p[2], 1e-6)) tmp.add(ContactPoint{fa.p[0], q, nt, -s});
  } else {
    clipFeatures(t, fa, true, nt, margin, tmp);
  }
  for (int k = 0; k < tmp.count; ++k) {
    bool dup = false;  // neighbouring triangles share edges, and their clips share points
    for (int j = 0; j < out.count; ++j)
      if ((out.p[j].pA - tmp.p[k].pA).squaredNorm() < 1e-6) {
        if (tmp.p[k].depth > out.p[j].depth) out.p[j] = tmp.p[k];
        dup = true;
        break;
      }
    if (!dup) out.add(tmp.p[k]);
  }
}

// A clipped patch's end: where clipping found no point, one at `fallback`, between the bodies,
// with the pair's depth along n; then at most four points.
void finishPatch(const Vec3& fallback, const Vec3& n, double depth, ContactPatch& out) {
  if (out.count == 0) out.add(ContactPoint{fallback - 0.5 * depth * n, fallback + 0.5 * depth * n, n, depth});
  reducePatch(out);
}

// Convex A and B touching (depth > 0) or close (depth < 0) along n, from B to A: the points of
// their supporting features. `fallback` is a point between them for when clipping finds none.
void fromNormal(const Shape& sA, const Pose& poseA, const Shape& sB, const Pose& poseB, const Vec3& n, double depth,
                double margin, const Vec3& fallback, ContactPatch& out) {
  const Feature fA = supportingFeature(sA, poseA, -n);
  const Feature fB = supportingFeature(sB, poseB, n);
  if (fA.count == 1) {
    out.add(ContactPoint{fA.p[0], fA.p[0] + depth * n, n, depth});
    return;
  }
  if (fB.count == 1) {
    out.add(ContactPoint{fB.p[0] - depth * n, fB.p[0], n, depth});
    return;
  }
  // The reference is the bigger feature; between two faces, the one facing the normal best.
  bool refIsB;
  if (fA.count != fB.count && (fA.count < 3 || fB.count < 3)) {
    refIsB = fB.count > fA.count;
  } else if (fA.count >= 3) {
    const double aB = std::abs(polygonNormal(fB).normalized().dot(n));
    const double aA = std::abs(polygonNormal(fA).normalized().dot(n));
    refIsB = aB >= aA;
  } else {
    refIsB = true;
  }
  clipFeatures(refIsB ? fB : fA, refIsB ? fA : fB, refIsB, n, margin, out);
  finishPatch(fallback, n, depth, out);
}

// fromNormal's clipping for two boxes whose supporting features along the normal are both faces
// (a box resting on a box), done in the reference box's frame, where its face is a rectangle and
// each side plane a test of one coordinate: the overlap's corners within the margin, unreduced.
// n: the unit normal from B to A. False where either feature is an edge or a corner.
bool boxFaceCorners(const Vec3& hA, const Vec3& hB, const BoxPair& g, const Pose& poseA, const Pose& poseB,
                    const Vec3& n, double margin, ContactPatch& out) {
  // Each box's side towards the other in its own frame, turned there by its quaternion as
  // supportingFeature turns it: where the normal is one box's face axis, the other two components
  // are rounding, and their signs pick the corner each face's walk starts at. The points then come
  // in the general clipping's order, which is the order the solver takes them in: starting every
  // face at one fixed corner biases the sequential solve (docs/collision.md, "The points' order").
  const Vec3 dA = poseA.unrotate(-n), dB = poseB.unrotate(n);
  const int kA = faceAxis(dA), kB = faceAxis(dB);
  if (kA < 0 || kB < 0) return false;
  // The reference face is the one facing the normal best; u is the direction from it towards the
  // incident box, in the reference box's frame; dI the incident box's side towards it, in its own.
  const bool refIsB = std::abs(dB[kB]) >= std::abs(dA[kA]);
  const Vec3& hR = refIsB ? hB : hA;
  const Vec3& hI = refIsB ? hA : hB;
  const Vec3& u = refIsB ? dB : dA;
  const Vec3& dI = refIsB ? dA : dB;
  const int kR = refIsB ? kB : kA, kI = refIsB ? kA : kB;
  // The incident face's corners in the reference box's frame, and the reference face's sides, in
  // the order supportingFeature walks each face: from the corner the direction points at, its
  // first free axis flipped, then the second, then the first back.
  const auto walk = [](const Vec3& d, int k, const Vec3& h, Vec3* corners) {
    Vec3 c;
    for (int i = 0; i < 3; ++i) c[i] = d[i] >= 0 ? h[i] : -h[i];
    const int a0 = k == 0 ? 1 : 0, a1 = k == 2 ? 1 : 2;
    corners[0] = c;
    c[a0] = -c[a0];
    corners[1] = c;
    c[a1] = -c[a1];
    corners[2] = c;
    c[a0] = -c[a0];
    corners[3] = c;
  };
  Vec3 bufA[8], bufB[8], ref[4];
  walk(dI, kI, hI, bufA);
  for (int k = 0; k < 4; ++k) bufA[k] = refIsB ? Vec3(g.R.transpose() * (bufA[k] - g.t)) : Vec3(g.R * bufA[k] + g.t);
  walk(u, kR, hR, ref);
  // Sutherland-Hodgman against the reference face's four sides in turn: side i, from corner i to
  // corner i + 1, keeps the points on the face's side of it, |x_r| <= hR_r on the axis r across it.
  Vec3* cur = bufA;
  Vec3* nxt = bufB;
  int count = 4;
  for (int side = 0; side < 4 && count > 0; ++side) {
    const Vec3& e0 = ref[side];
    const Vec3& e1 = ref[(side + 1) % 4];
    const int r = e0[(kR + 1) % 3] == e1[(kR + 1) % 3] ? (kR + 1) % 3 : (kR + 2) % 3;
    const double sg = e0[r] > 0 ? 1.0 : -1.0;
    int k = 0;
    for (int i = 0; i < count; ++i) {
      const Vec3& a = cur[i];
      const Vec3& b = cur[(i + 1) % count];
      const double da = sg * a[r] - hR[r], db = sg * b[r] - hR[r];
      if (da <= 0) nxt[k++] = a;
      if ((da < 0 && db > 0) || (da > 0 && db < 0)) nxt[k++] = a + (da / (da - db)) * (b - a);
    }
    count = k;
    std::swap(cur, nxt);
  }
  // Each point's separation s from the reference face, measured along u (the normal): the
  // incident point p and its partner q = p - s u on the reference face's plane.
  const double den = std::abs(u[kR]);
  if (den < 0.1) return true;  // the reference face nearly along the normal: no meaningful projection
  const double sideR = u[kR] >= 0 ? 1.0 : -1.0;
  const Mat3& W = refIsB ? g.RB : g.RA;
  const Vec3& origin = refIsB ? poseB.p : poseA.p;
  for (int i = 0; i < count; ++i) {
    const Vec3& p = cur[i];
    const double sep = (sideR * p[kR] - hR[kR]) / den;
    if (sep > margin) continue;
    const Vec3 onI = W * p + origin, onR = W * Vec3(p - sep * u) + origin;
    out.add(ContactPoint{refIsB ? onI : onR, refIsB ? onR : onI, n, -sep});
  }
  return true;
}

}  // namespace

bool roundBoxContact(const Shape& round, const Pose& poseR, const Shape& box, const Pose& poseBox, double margin,
                     Vec3& n, double& gap, Vec3& onBox) {
  Vec3 c0, c1, onSeg = Vec3::Zero(), axis = Vec3::UnitY();
  coreSegment(round, poseR, c0, c1);
  const double satGap = roundBoxGapLowerBound(round, poseR, box.halfExtents, poseBox, &axis);
  if (satGap > margin) return false;
  if (satGap + round.radius > kTouching) {  // the core is outside the box
    const double d = segmentBoxDistance(c0, c1, box.halfExtents, poseBox, onSeg, onBox);
    gap = d - round.radius;
    if (gap > margin) return false;
    n = (onSeg - onBox) / d;
  } else {
    gap = satGap;
    n = axis;
    onBox = 0.5 * (c0 + c1);
  }
  return true;
}

bool boxFacesClipped(const Vec3& hA, const Pose& A, const Vec3& hB, const Pose& B, const Vec3& n, double margin,
                     ContactPatch& out) {
  const BoxPair g(A, B);
  out.count = 0;
  return boxFaceCorners(hA, hB, g, A, B, n, margin, out);
}

double boxBoxGap(const Vec3& hA, const Pose& A, const Vec3& hB, const Pose& B, Vec3& axis) {
  const BoxPair g(A, B);
  Vec3 axisA;
  const double gap = boxGapLowerBound(hA, hB, g, &axisA);
  axis = g.RA * axisA;
  return gap;
}

void Narrowphase::collide(const Shape& sA, const CollisionShape& cA, const Pose& poseA, const Shape& sB,
                          const CollisionShape& cB, const Pose& poseB, double margin, ContactPatch& out) {
  out.count = 0;
  if (sB.type == ShapeType::Plane) {
    // Analytic: A's feature towards the plane (FCL's halfspace has no distance query).
    const Vec3 pn = poseB.rotate(sB.normal).normalized();
    const double off = sB.offset + pn.dot(poseB.p);
    const Feature fa = supportingFeature(sA, poseA, -pn);
    for (int i = 0; i < fa.count; ++i) {
      const double s = pn.dot(fa.p[i]) - off;
      if (s <= margin) out.add(ContactPoint{fa.p[i], fa.p[i] - s * pn, pn, -s});
    }
    reducePatch(out);
    return;
  }
  if (sA.type == ShapeType::Box && sB.type == ShapeType::Box) {
    const BoxPair g(poseA, poseB);
    Vec3 axisA;
    bool face = true;
    const double gap = boxGapLowerBound(sA.halfExtents, sB.halfExtents, g, &axisA, &face, margin);
    if (gap > margin) return;  // further apart than the margin: no contact and no speculative point
    // The separating axis is the normal and its gap the (negative) depth, whether the boxes are
    // apart within the margin, touching (stacked by a generator) or overlapping. Overlapping, the
    // axis of least overlap over all 15 is the exact penetration depth and direction; FCL, as
    // called here, gives the same on face contacts and an estimate on edge contacts, and
    // allocates on every query (the fast path is tested against it on random pairs). Apart, the
    // gap is a lower bound on the distance (exact when a face is closest), so a speculative point
    // may stop the boxes a little early, never late; FCL would need collide and distance here
    // (and for touching boxes a third, nudged collide): its box-box distance was the largest part
    // of s1 on a collapsing pyramid. useGeneralPath(true) restores FCL's, and the general clipping.
    if (!generalPath_ || gap > kTouching || (gap >= -kTouching && face)) {
      const Vec3 mid = 0.5 * (poseA.p + poseB.p), n = g.RA * axisA;
      if (generalPath_ || !boxFaceCorners(sA.halfExtents, sB.halfExtents, g, poseA, poseB, n, margin, out))
        fromNormal(sA, poseA, sB, poseB, n, -gap, margin, mid, out);
      else
        finishPatch(mid, n, -gap, out);
      return;
    }
  }
  if (isRound(sA.type) && isRound(sB.type)) {
    // Spheres and capsules are points and segments grown by a radius: the closest points of the
    // core segments give the normal and the distance in closed form. libccd's GJK and EPA for
    // these pairs were most of s1 on the ragdoll pile (docs/collision.md). Crossing cores (no
    // direction) are left to FCL.
    Vec3 a0, a1, b0, b1, cp, cq;
    coreSegment(sA, poseA, a0, a1);
    coreSegment(sB, poseB, b0, b1);
    closestPointsOfSegments(a0, a1, b0, b1, cp, cq);
    const Vec3 d = cp - cq;
    const double len = d.norm();
    if (len > kTouching) {
      const double gap = len - sA.radius - sB.radius;
      if (gap > margin) return;
      const Vec3 n = d / len;  // from B to A
      fromNormal(sA, poseA, sB, poseB, n, -gap, margin, 0.5 * ((cp - sA.radius * n) + (cq + sB.radius * n)), out);
      return;
    }
  }
  if (!generalPath_ && ((sA.type == ShapeType::Box && isRound(sB.type)) || (isRound(sA.type) && sB.type == ShapeType::Box))) {
    // A sphere or capsule against a box: its core segment against the box. Apart (the common
    // case: a limb resting on the ground, its core above the surface), the closest points give
    // the normal and the distance exactly; a core that reaches into the box takes the axis of
    // least overlap among the box's faces and the axes across the segment and each box edge
    // (the separating axes of a segment and a box), the radius added. libccd's MPR, which FCL
    // uses here, estimates the depth (2 to 3 % off at 10 cm, far more at deep overlaps) and
    // allocates on every query.
    const bool aRound = isRound(sA.type);
    Vec3 n, onBox;  // n from the box to the round shape
    double gap;
    if (!roundBoxContact(aRound ? sA : sB, aRound ? poseA : poseB, aRound ? sB : sA, aRound ? poseB : poseA, margin, n,
                         gap, onBox))
      return;
    if (!aRound) n = -n;  // from B to A
    const Vec3 fallback = aRound ? Vec3(onBox + 0.5 * gap * n) : Vec3(onBox - 0.5 * gap * n);
    fromNormal(sA, poseA, sB, poseB, n, -gap, margin, fallback, out);
    return;
  }
  const bool mesh = sB.type == ShapeType::TriangleMesh;
  const fcl::Transform3d tA = toFcl(compose(poseA, cA.offset)), tB = toFcl(compose(poseB, cB.offset));
  request_.num_max_contacts = mesh ? 64 : 4;
  result_.clear();
  fcl::collide(cA.geometry.get(), tA, cB.geometry.get(), tB, request_, result_);
  const size_t nc = result_.numContacts();

  if (nc == 0) {
    // Not touching: within the margin, speculative points (depth < 0) let the bodies close the
    // gap in this step and no further, instead of sinking in and being pushed out.
    distanceResult_.clear();
    fcl::distance(cA.geometry.get(), tA, cB.geometry.get(), tB, distanceRequest_, distanceResult_);
    const double d = distanceResult_.min_distance;
    if (d > margin) return;
    if (!(d > kTouching)) {
      // Exactly touching (boxes stacked by a generator): not colliding for FCL and no direction
      // from the nearest points. Nudge A towards B by kTouching to get FCL's normal; the points
      // still come from the true poses.
      Vec3 u = poseA.p - poseB.p;
      u = u.norm() > 0 ? Vec3(u.normalized()) : Vec3::UnitY();
      fcl::Transform3d nudged = tA;
      nudged.translation() -= kTouching * u;
      result_.clear();
      fcl::collide(cA.geometry.get(), nudged, cB.geometry.get(), tB, request_, result_);
      if (result_.numContacts() == 0) return;
      size_t deepest = 0;
      for (size_t i = 1; i < result_.numContacts(); ++i)
        if (result_.getContact(i).penetration_depth > result_.getContact(deepest).penetration_depth) deepest = i;
      Vec3 n = -result_.getContact(deepest).normal;
      if (n.squaredNorm() < 1e-24) return;
      if (mesh) {
        const auto& fc = result_.getContact(deepest);
        againstTriangle(sA, poseA, *sB.mesh, poseB, fc.b2 >= 0 ? fc.b2 : fc.b1, margin, out);
        reducePatch(out);
        return;
      }
      fromNormal(sA, poseA, sB, poseB, n.normalized(), 0.0, margin, result_.getContact(deepest).pos, out);
      return;
    }
    if (mesh) {
      // FCL's nearest points for shape-mesh pairs come in mixed frames: only the triangle is used.
      const intptr_t tri = distanceResult_.b1 >= 0 ? distanceResult_.b1 : distanceResult_.b2;
      againstTriangle(sA, poseA, *sB.mesh, poseB, tri, margin, out);
      reducePatch(out);
      return;
    }
    const Vec3 pa = distanceResult_.nearest_points[0], pb = distanceResult_.nearest_points[1];
    fromNormal(sA, poseA, sB, poseB, (pa - pb) / d, -d, margin, 0.5 * (pa + pb), out);
    return;
  }

  if (mesh) {
    // One FCL contact per triangle. FCL's shape-mesh traversal puts the triangle index in b1
    // even with the mesh second.
    for (size_t i = 0; i < nc; ++i) {
      const auto& fc = result_.getContact(i);
      againstTriangle(sA, poseA, *sB.mesh, poseB, fc.b2 >= 0 ? fc.b2 : fc.b1, margin, out);
    }
    if (out.count == 0) {
      // On a ridge between triangles no feature projects inside one: use FCL's points.
      for (size_t i = 0; i < nc && out.count < kMaxPatchPoints; ++i) {
        const auto& fc = result_.getContact(i);
        Vec3 n = fc.normal;
        if (n.squaredNorm() < 1e-24) continue;
        n.normalize();
        if (n.dot(poseA.p - fc.pos) < 0) n = -n;
        const double d = fc.penetration_depth;
        out.add(ContactPoint{fc.pos - 0.5 * d * n, fc.pos + 0.5 * d * n, n, d});
      }
    }
    reducePatch(out);
    return;
  }

  // The deepest FCL contact gives the normal (FCL's points from A to B; ours from B to A).
  size_t deepest = 0;
  for (size_t i = 1; i < nc; ++i)
    if (result_.getContact(i).penetration_depth > result_.getContact(deepest).penetration_depth) deepest = i;
  const auto& fc = result_.getContact(deepest);
  Vec3 n = -fc.normal;
  if (n.squaredNorm() < 1e-24) return;
  fromNormal(sA, poseA, sB, poseB, n.normalized(), fc.penetration_depth, margin, fc.pos, out);
}

}  // namespace substep
