// What a scene and a solver may ask for: every number's physical range, in one place.
// Scene files (scene_file.cpp), the command line and method specs (settings.cpp) check against
// these and refuse what lies outside with the value's path and the range (docs/robustness.md).
// Inside them nothing crashes or loops: FCL's AABB tree builds from finite boxes, libccd's MPR
// (which has no iteration cap) works on well-scaled shapes, and the solvers stay in floating
// point's range until the divergence guard (world.h) stops a run.
#pragma once

#include <cstddef>
#include <string>

namespace substep {

// An interval of the reals, closed unless marked open.
struct Range {
  double lo, hi;
  bool loOpen = false, hiOpen = false;

  bool contains(double x) const {  // false for NaN
    return (loOpen ? x > lo : x >= lo) && (hiOpen ? x < hi : x <= hi);
  }
  // "in [0.001, 10000]", "in (0, 2)", ">= 0" (hi infinite)
  std::string text() const;
  // "a number in [...]" / "an integer in [...]", the words an error message uses.
  std::string expected(bool integer = false) const;
};

namespace limits {

// Shapes: every dimension (radius, half extent, half height, a mesh's half size after scaling).
// libccd's MPR loops without end on shapes near 1e22 m, and FCL's tree overflows near 1e154.
inline constexpr Range kSize{1e-3, 1e4};                        // [m]
// Positions of bodies, anchors, camera targets: each coordinate. A tenth of the divergence guard
// (world.h: 1e6 m), so that a run starting inside it is not "diverged at step 1".
inline constexpr Range kCoordinate{-1e5, 1e5};                  // [m]
inline constexpr Range kSpeed{-1e4, 1e4};                       // each component [m/s]
inline constexpr Range kAngularSpeed{-1e4, 1e4};                // each component [rad/s]
inline constexpr Range kMass{1e-6, 1e9};                        // a body's, given or from density [kg]
inline constexpr Range kDensity{1e-3, 1e6};                     // [kg/m^3]
inline constexpr Range kGravity{-1e3, 1e3};                     // each component [m/s^2]
inline constexpr Range kFriction{0, 10};                        // Coulomb μ
inline constexpr Range kRestitution{0, 1};                      // e
inline constexpr Range kJointAngle{-6.2832, 6.2832};            // joint limits, ragdoll yaw [rad]
inline constexpr Range kSwing{0, 3.1416, true};                  // cone half angle [rad]
inline constexpr Range kDegrees{-1e5, 1e5};                     // camera yaw, orbit [degrees]
inline constexpr Range kMotorSpeed{-1e4, 1e4};                  // [rad/s]
inline constexpr Range kTorque{0, 1e12};                        // motor cap [N m]; 0: unbounded
inline constexpr Range kLength{0, 1e4};                         // rest lengths, gaps, spacings [m]
inline constexpr Range kDistance{1e-3, 1e5};                    // camera distance [m]
inline constexpr Range kScale{1e-3, 1e3};                       // mesh and ragdoll scale factors

// Totals. Bodies and joints are capped so that a typing error (a 400-level pyramid, 80 200
// boxes) is a message rather than minutes of stepping; `--max-bodies` raises the cap.
inline constexpr int kDefaultMaxBodies = 20000;      // the 10 000-box pile and its ground fit
inline constexpr int kMaxBodiesCeiling = 1000000;               // what --max-bodies accepts
// Broadphase pairs per body beyond which a step stops: 20 000 bodies started inside each other
// would otherwise make 2e8 pairs. A settled pile has about 6 per box, a ragdoll pile 10.
inline constexpr int kMaxPairsPerBody = 64;
inline constexpr int kMinPairCap = 4096;
// Threads a step may run on (SolverSettings::threads).
inline constexpr int kMaxThreads = 256;

// Files and text.
inline constexpr size_t kMaxSceneBytes = 64u << 20;             // a scene file [bytes]
inline constexpr size_t kMaxMeshBytes = 256u << 20;             // a mesh file [bytes]
inline constexpr size_t kMaxMeshTriangles = 2000000;
inline constexpr int kMaxNesting = 64;                          // JSON arrays and objects inside each other
inline constexpr size_t kMaxNameLength = 256;                   // body, joint, camera names [characters]
inline constexpr size_t kMaxMessageValue = 60;                  // a value quoted in a message [characters]

}  // namespace limits

// Numbers as messages print them: shortest round-trip form ("0.001", "1e+22", "nan").
std::string numberText(double x);

}  // namespace substep
