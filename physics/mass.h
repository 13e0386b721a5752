// Mass properties of shapes: mass, centre of mass and inertia tensor of a uniform solid.
// Bodies keep only the principal moments, so convex meshes are first moved into their
// principal frame (toPrincipalFrame) and the scene's pose is composed with that frame.
#pragma once

#include "physics/math.h"
#include "physics/model.h"

namespace substep {

struct MassProperties {
  double mass = 0;                // [kg]
  Vec3 com = Vec3::Zero();        // centre of mass in the shape's frame [m]
  Mat3 inertia = Mat3::Zero();    // about the centre of mass, axes of the shape's frame [kg m^2]
};

// Uniform solid of the given density [kg/m^3]. Spheres, boxes, capsules and cylinders are
// centred on their frame (com = 0, diagonal inertia). Convex meshes use exact polyhedron
// integrals; their faces must wind counter-clockwise seen from outside (else the volume is < 0).
// Planes and triangle meshes have no volume: std::invalid_argument.
MassProperties shapeMassProperties(const Shape& shape, double density);

// The same for a closed triangle mesh (signed volume: negative for inward-facing triangles).
MassProperties meshMassProperties(const Mesh& mesh, double density);

// Volume of a closed triangle mesh [m^3] (signed, as above).
double meshVolume(const Mesh& mesh);

// Re-expresses the mesh's vertices in its principal frame: origin at the centre of mass, axes
// the eigenvectors of the inertia tensor (a right-handed frame). Returns the pose of that frame in
// the mesh's original (file) frame, so a body placed at `filePose` in a scene has
// bodyPose = filePose ∘ principal, i.e. x = filePose.apply(principal.p), q = filePose.q * principal.q.
// If the inertia is already diagonal the axes are kept as they are.
Pose toPrincipalFrame(Mesh& mesh);

// Fill mass, invMass, inertia (principal moments: the diagonal of the inertia tensor about the
// centre of mass, which must be the body origin) and invInertia. Static bodies get zeros.
// Throws std::invalid_argument for a non-positive density/mass or a shape without volume.
void setMassFromDensity(Body& body, double density);
void setMassFromMass(Body& body, double mass);

}  // namespace substep
