// Scene generators: many bodies (and joints) from a few parameters, as a scene file's
// "generators" list uses them. Each appends to Scene::model and Scene::initial in step.
#pragma once

#include "physics/scene_file.h"

#include <optional>
#include <string>
#include <vector>

namespace substep {

struct GeneratorInfo {
  std::string type, summary;
};
// One line per generator type, for `substep scenes`.
const std::vector<GeneratorInfo>& generatorList();

// What every generated dynamic body is made of.
struct BodyMaterial {
  std::optional<double> mass;   // per body [kg]; when unset, `density` decides
  double density = 1000;        // [kg/m^3]
  double friction = 0.5;
  double restitution = 0;
  int group = -1;
  uint32_t category = 1, mask = 0xFFFFFFFFu;  // collision filtering (model.h)
  int filterGroup = 0;                         // < 0: the bodies made together never touch each other
};

// `count` boxes one above the other; `position` is the centre of the bottom face of the bottom
// box, `gap` the vertical space between neighbours. Boxes are named <name>_0 (bottom) ...
struct StackParams {
  int count = 1;
  Vec3 halfExtents = Vec3::Constant(0.5);
  Vec3 position = Vec3::Zero();
  double gap = 0;
  std::string name = "stack";
  BodyMaterial material;
};

// A pyramid in the XY plane: level 0 has `levels` boxes in a row along X, each level above one
// fewer, centred on the one below and touching it. `position` is the centre of the bottom row's
// bottom face, `gap` the horizontal space between neighbours. Names <name>_<level>_<i>.
struct PyramidParams {
  int levels = 1;
  Vec3 halfExtents = Vec3::Constant(0.5);
  Vec3 position = Vec3::Zero();
  double gap = 0.01;
  std::string name = "pyramid";
  BodyMaterial material;
};

// A static sphere <name>_anchor (radius anchorRadius) at `anchor`, and links <name>_0 ... whose
// centres lie at anchor + (k + 1/2) spacing direction, local Y along `direction`, joined at
// anchor + k spacing direction (link 0 to the anchor body). Joints are ball or hinge (axis
// horizontal, perpendicular to `direction`), named <name>_joint_<k>, with collide off.
struct ChainParams {
  int count = 1;
  Shape link;                   // capsule, box or sphere
  Vec3 anchor = Vec3::Zero();
  Vec3 direction = Vec3::UnitX();
  double spacing = 1;
  std::string name = "chain";
  BodyMaterial material;
  JointType joint = JointType::Ball;
  double anchorRadius = 0.05;
};

// Humanoid ragdolls of 15 bodies: pelvis, spine, chest (boxes and a capsule), head (sphere),
// upper and lower arms, upper and lower legs (capsules), feet (boxes), 68 kg by default with
// the masses of an adult (pelvis 10 kg, forearm with hand 1 kg), joined by cone-twist joints
// (spine, neck, shoulders, hips) and hinges (elbows, knees, ankles) with anatomical limits.
// Ragdolls come in layers of `columns`: ragdoll k is column c = k mod columns of layer
// L = k / columns. It stands (in its own frame: Y up, facing +Z) with its pelvis centre at
// position + L offset + Ry(L yaw) (c - (columns-1)/2) spread, turned by orientation and then by
// L yaw about Y (so with yaw 90 degrees the layers cross). Bodies are named <name>_<k>_<part>;
// each ragdoll is its own group.
struct RagdollParams {
  int count = 1;
  int columns = 1;
  Vec3 position = Vec3::Zero();
  Quat orientation = Quat::Identity();
  Vec3 offset = Vec3(0, 1.2, 0);  // between consecutive layers [m]
  Vec3 spread = Vec3(0.8, 0, 0);  // between the columns of a layer, before the layer's yaw [m]
  double yaw = 0;                 // extra turn of each layer about Y over the previous [rad]
  Vec3 velocity = Vec3::Zero();   // of every body [m/s]
  double scale = 1;               // size; masses scale with its cube
  double mass = 68;               // of one ragdoll at scale 1 [kg]
  std::string name = "ragdoll";
  BodyMaterial material;          // friction, restitution, group (mass/density unused)
};
// The parts, in the order their bodies are added.
const std::vector<std::string>& ragdollParts();

// These throw std::invalid_argument for out-of-range parameters (scene parsing checks first).
void addStack(Scene& scene, const StackParams& p);
void addRagdoll(Scene& scene, const RagdollParams& p);
void addPyramid(Scene& scene, const PyramidParams& p);
void addChain(Scene& scene, const ChainParams& p);

// Building blocks shared with the scene parser.

// Appends a body and its initial state; returns its index.
int addBody(Scene& scene, const Body& body, const BodyState& state);

// A joint between bodies a and b from world data at the initial configuration: anchors (the same
// point for all but springs), and an axis (unit). The axis and a unit reference vector
// perpendicular to it are stored in both body frames, so the initial relative angle is zero.
// Spring rest length is set to the initial anchor distance.
Joint makeJoint(const Scene& scene, JointType type, int a, int b, const Vec3& worldAnchorA,
                const Vec3& worldAnchorB, const Vec3& worldAxis);

}  // namespace substep
