#include "render/gl_renderer.h"

#include "render/fxaa.h"
#include "render/meshes.h"
#include "render/text.h"

// OSMesa exports every gl* entry point, so the prototypes are linked directly: no loader.
#define GL_GLEXT_PROTOTYPES 1
#include <GL/osmesa.h>
#include <GL/gl.h>
#include <GL/glext.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>

namespace substep::render {

namespace {

// ---- shaders (GLSL 3.30 core) ----

const char* kMeshVS = R"(#version 330 core
layout(location = 0) in vec3 aPos;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in float aCap;
layout(location = 3) in vec4 iRot;          // quaternion x, y, z, w
layout(location = 4) in vec4 iPosStretch;   // position, capsule stretch
layout(location = 5) in vec4 iScaleFlags;   // scale, flags (which program draws it: unused here)
layout(location = 6) in vec4 iColour;       // rgb, highlight
uniform mat4 uViewProj;
uniform mat4 uLightMatrix;
uniform float uNormalBias;
out vec3 vShadow;
out vec3 vWorld;
out vec3 vNormal;
flat out vec3 vColour;      // per instance: not interpolated (llvmpipe pays per component and pixel)
flat out float vHighlight;
vec3 qrot(vec4 q, vec3 v) { return v + 2.0 * cross(q.xyz, cross(q.xyz, v) + q.w * v); }
void main() {
  vec3 local = aPos * iScaleFlags.xyz + vec3(0.0, aCap * iPosStretch.w, 0.0);
  vWorld = qrot(iRot, local) + iPosStretch.xyz;
  vNormal = qrot(iRot, aNormal / iScaleFlags.xyz);   // inverse-transpose of a scale is its inverse
  vColour = iColour.rgb;
  vHighlight = iColour.a;
  gl_Position = uViewProj * vec4(vWorld, 1.0);
  // The light's projection is orthographic, so its coordinates interpolate exactly.
  vShadow = (uLightMatrix * vec4(vWorld + normalize(vNormal) * uNormalBias, 1.0)).xyz * 0.5 + 0.5;
}
)";

// Compiled four times: MODE 0 (lit) with GRID 0 (bodies) and GRID 1 (statics flagged kGrid: the
// grid on upward faces), MODE 1 (overlay: flat) and MODE 2 (depth only, the shadow pass): llvmpipe
// runs both sides of a branch, even on a uniform, so one program with a mode uniform made the
// shadow pass pay for the lighting, and one with a grid branch made every body pay for the grid.
const char* kMeshFS = R"(
in vec3 vShadow;
in vec3 vWorld;
in vec3 vNormal;
flat in vec3 vColour;
flat in float vHighlight;
uniform vec3 uEye;
uniform vec3 uLightDir;         // the direction light travels
uniform sampler2DShadow uShadowMap;
uniform vec3 uHorizon;
uniform vec2 uFog;              // start, end [m]
out vec4 fragColour;

// The alpha carries the pixel's luma for the anti-aliasing on the CPU (render/fxaa.h): 0-127 in
// bits 1-7, bit 0 set on faces that are smooth as drawn (the gridded ground). Multisampled without
// it (COVERAGE_ALPHA), the alpha is 1, so that after the resolve it says how much the solids cover.
float lumaAlpha(vec3 c, float smoothFace) {
#if COVERAGE_ALPHA
  return 1.0;
#else
  return (floor(clamp(dot(c, vec3(0.299, 0.587, 0.114)), 0.0, 1.0) * 127.0 + 0.5) * 2.0 + smoothFace) / 255.0;
#endif
}

void main() {
#if MODE == 2
  fragColour = vec4(1.0);
#else
  vec3 n = normalize(vNormal);
  if (!gl_FrontFacing) n = -n;   // the inside of a bowl, or a mesh wound the other way
  vec3 toEye = uEye - vWorld;
  float eyeDist2 = dot(toEye, toEye), invEyeDist = inversesqrt(eyeDist2);
  vec3 v = toEye * invEyeDist;
#if MODE == 1
  vec3 shade = vColour * (0.55 + 0.45 * abs(dot(n, v)));
  fragColour = vec4(shade, lumaAlpha(shade, 0.0));
#else
  vec3 albedo = vColour;
#if GRID
  bool grid = n.y > 0.5;
  if (grid) {
    // Anti-aliased grid lines every metre, stronger every five, fading where a pixel spans a line.
    vec2 w = fwidth(vWorld.xz);
    vec2 g1 = abs(fract(vWorld.xz - 0.5) - 0.5) / max(w, 1e-5);
    vec2 g5 = abs(fract(vWorld.xz / 5.0 - 0.5) - 0.5) * 5.0 / max(w, 1e-5);
    float fade = 1.0 - smoothstep(0.15, 0.5, max(w.x, w.y));
    float minor = (1.0 - min(min(g1.x, g1.y), 1.0)) * fade;
    float major = 1.0 - min(min(g5.x, g5.y) / 1.5, 1.0);
    albedo *= 1.0 - 0.22 * max(minor, major);
  }
#else
  const bool grid = false;
#endif
  albedo = mix(albedo, vec3(1.0, 0.9, 0.3), 0.35 * vHighlight);
  vec3 L = -uLightDir;
  float ndl = max(dot(n, L), 0.0);
  // Outside the map (beyond the casters) is lit. One hardware-filtered tap: the 2x2 texels
  // around the point, compared and blended (llvmpipe pays dearly for each lookup).
  float sh = 1.0;
#if SHADOW
  if (ndl > 0.0 && clamp(vShadow, 0.0, 1.0) == vShadow && vShadow.z < 1.0)
    sh = texture(uShadowMap, vShadow);
#endif
  vec3 h = normalize(L + v);
  // Powers by squaring: llvmpipe's pow() costs as much as the rest of the shader.
  float s2 = max(dot(n, h), 0.0);
  s2 *= s2; s2 *= s2; s2 *= s2; s2 *= s2; s2 *= s2;   // ^32
  float spec = s2 * 0.25 * step(0.0, ndl);
  // Sky and ground ambient, plus a weak light from the eye so faces away from the sun keep their shape.
  vec3 ambient = mix(vec3(0.20, 0.19, 0.18), vec3(0.36, 0.40, 0.47), 0.5 + 0.5 * n.y) + 0.18 * max(dot(n, v), 0.0);
  vec3 col = albedo * (ambient + 0.78 * ndl * sh * vec3(1.0, 0.97, 0.9)) + spec * sh;
  float rim = 1.0 - max(dot(n, v), 0.0);
  col += vHighlight * rim * rim * vec3(1.0, 0.8, 0.2);
  col = mix(col, uHorizon, smoothstep(uFog.x, uFog.y, eyeDist2 * invEyeDist));
  fragColour = vec4(col, lumaAlpha(col, grid ? 1.0 : 0.0));
#endif
#endif
}
)";

// The sky: a triangle covering the viewport at the far plane, drawn after the solids with the
// depth test, so only the pixels they left uncovered pay for it (llvmpipe skips blocks whose depth
// test fails before shading). Multisampled without FXAA it is drawn instead after the resolve,
// single-sampled, under the solids ("under" blending by the alpha the solids left): cheaper than
// a sky written to every sample, and silhouettes against it keep their coverage. Its colour
// follows the elevation of the view ray; the ray of a far-plane point is affine in screen
// position, so it is computed per vertex.
const char* kSkyVS = R"(#version 330 core
uniform mat4 uInvViewProj;
out vec3 vRay;
void main() {
  vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0);
  vec4 a = uInvViewProj * vec4(p, -1.0, 1.0);
  vec4 b = uInvViewProj * vec4(p, 1.0, 1.0);
  vRay = b.xyz / b.w - a.xyz / a.w;
  gl_Position = vec4(p, 1.0, 1.0);
}
)";

const char* kSkyFS = R"(
in vec3 vRay;
uniform vec3 uHorizon;
out vec4 fragColour;
void main() {
  float y = vRay.y * inversesqrt(dot(vRay, vRay));
  vec3 zenith = vec3(0.30, 0.45, 0.68), below = vec3(0.50, 0.52, 0.54);
  // sqrt(y) rather than a pow: llvmpipe pays per pixel.
  vec3 up = mix(uHorizon, zenith, sqrt(max(y, 0.0)));
  vec3 down = mix(uHorizon, below, min(1.0, -y * 4.0));
  vec3 c = y > 0.0 ? up : down;
#if COVERAGE_ALPHA
  fragColour = vec4(c, 1.0);  // drawn under the resolved solids
#else
  // Luma in the alpha, as the meshes write it (render/fxaa.h).
  fragColour = vec4(c, floor(clamp(dot(c, vec3(0.299, 0.587, 0.114)), 0.0, 1.0) * 127.0 + 0.5) * 2.0 / 255.0);
#endif
}
)";

const char* kTextVS = R"(#version 330 core
layout(location = 0) in vec2 aPos;      // pixels, y down
layout(location = 1) in vec2 aUV;       // atlas; x < 0: solid
layout(location = 2) in vec4 aColour;
uniform vec2 uFrame;
out vec2 vUV;
out vec4 vColour;
void main() {
  vUV = aUV;
  vColour = aColour;
  gl_Position = vec4(aPos.x / uFrame.x * 2.0 - 1.0, 1.0 - aPos.y / uFrame.y * 2.0, 0.0, 1.0);
}
)";

const char* kTextFS = R"(#version 330 core
in vec2 vUV;
in vec4 vColour;
uniform sampler2D uAtlas;
out vec4 fragColour;
void main() {
  float a = vUV.x < 0.0 ? 1.0 : texture(uAtlas, vUV).r;
  fragColour = vec4(vColour.rgb, vColour.a * a);
}
)";

const Vec3f kHorizon(0.78f, 0.82f, 0.86f);

GLuint compile(GLenum type, const char* src, const char* what) {
  GLuint s = glCreateShader(type);
  glShaderSource(s, 1, &src, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[4096];
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    throw RenderError(std::string("GL: the ") + what + " shader does not compile: " + log);
  }
  return s;
}

GLuint link(const char* vs, const char* fs, const char* what) {
  const GLuint v = compile(GL_VERTEX_SHADER, vs, what), f = compile(GL_FRAGMENT_SHADER, fs, what);
  GLuint p = glCreateProgram();
  glAttachShader(p, v);
  glAttachShader(p, f);
  glLinkProgram(p);
  glDeleteShader(v);
  glDeleteShader(f);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[4096];
    glGetProgramInfoLog(p, sizeof log, nullptr, log);
    throw RenderError(std::string("GL: the ") + what + " program does not link: " + log);
  }
  return p;
}

struct GpuMesh {
  GLuint vao = 0, vbo = 0, ebo = 0;
  GLsizei count = 0;
};

// Per-instance data as the vertex shader reads it (locations 3-6).
struct GpuInstance {
  float rot[4];
  float posStretch[4];
  float scaleFlags[4];
  float colour[4];
};

GpuInstance pack(const Instance& in) {
  GpuInstance g;
  const Quatf q = in.rotation.normalized();
  g.rot[0] = q.x(), g.rot[1] = q.y(), g.rot[2] = q.z(), g.rot[3] = q.w();
  g.posStretch[0] = in.position.x(), g.posStretch[1] = in.position.y(), g.posStretch[2] = in.position.z();
  g.posStretch[3] = in.stretch;
  g.scaleFlags[0] = in.scale.x(), g.scaleFlags[1] = in.scale.y(), g.scaleFlags[2] = in.scale.z();
  g.scaleFlags[3] = static_cast<float>(in.flags);
  g.colour[0] = in.colour.x(), g.colour[1] = in.colour.y(), g.colour[2] = in.colour.z();
  g.colour[3] = in.highlight;
  return g;
}

// How large a length looks at a point: pixels on screen (perspective) or texels of the shadow map
// (orthographic), for choosing a round primitive's level of detail.
struct PixelScale {
  Vec3f eye = Vec3f::Zero();      // where distances (the draw order) are measured from
  Vec3f forward = Vec3f::Zero();  // perspective: the view direction (zero: orthographic)
  float perMetre = 1;             // pixels of a metre at depth 1 (perspective) or anywhere (orthographic)
  float zNear = 0.05f;
  float maxError = kMaxSilhouetteError;  // [pixels or texels]

  float pixels(float length, const Vec3f& at, float extent) const {
    if (forward.isZero()) return length * perMetre;
    // Depth of the instance's nearest point; anything reaching the near plane gets the finest level.
    const float depth = forward.dot(at - eye) - extent;
    return depth <= zNear ? std::numeric_limits<float>::infinity() : length * perMetre / depth;
  }
};

// What a view's camera makes of lengths: pixels on screen.
PixelScale screenScale(const DrawList& dl, const Viewport& vp) {
  PixelScale p;
  p.eye = dl.camera.eye;
  p.forward = (dl.camera.target - dl.camera.eye).normalized();
  const float aspect = static_cast<float>(vp.width) / static_cast<float>(std::max(vp.height, 1));
  p.perMetre = dl.camera.projection(aspect)(1, 1) * 0.5f * static_cast<float>(vp.height);
  p.zNear = dl.camera.zNear;
  return p;
}

int levelOf(const Instance& in, const PixelScale& scale) {
  if (!isRound(in.mesh)) return 0;
  const float radius = std::max(in.scale.x(), in.scale.z());
  return roundLevel(scale.pixels(radius, in.position, in.scale.maxCoeff() + std::abs(in.stretch)), scale.maxError);
}

struct TextVertex {
  float x, y, s, t;
  float r, g, b, a;
};

}  // namespace

struct GlRenderer::Impl {
  OSMesaContext ctx = nullptr;
  std::vector<uint8_t> dummy;  // OSMesa needs a buffer to make the context current; we draw into FBOs
  int width = 0, height = 0, samples = 1, shadowSize = 0;
  AntiAliasing antiAliasing = AntiAliasing::None;
  bool skyUnder = false;  // multisampled without FXAA: the sky goes under the resolved solids
  // The scene is drawn into drawFbo: msFbo (multisampled) resolved into sceneFbo by a blit, or
  // sceneFbo itself without multisampling. The text goes on sceneFbo, which is read back.
  GLuint sceneFbo = 0, sceneColour = 0, sceneDepth = 0;
  GLuint msFbo = 0, msColour = 0, msDepth = 0;
  GLuint drawFbo = 0;
  RawFrame raw;                         // render()'s frame as read back, reused
  std::vector<PixelRect> textRects;     // this frame's text panels, kept out of the anti-aliasing
  struct ShadowMap {
    GLuint fbo = 0, tex = 0;
  };
  std::vector<ShadowMap> shadowMaps;  // one per view of a frame, made on first use
  GLuint litProg[2][2] = {};  // [gridded][shadowed]: without shadows (--shadow-size 0) no lookup at all
  GLuint flatProg = 0, depthProg = 0, skyProg = 0, textProg = 0;
  GLuint instanceVbo = 0, emptyVao = 0, textVao = 0, textVbo = 0;
  std::vector<std::vector<GpuMesh>> primitives;  // by mesh id, then level of detail (round ones)
  std::map<const Mesh*, GpuMesh> custom;  // keyed by the model's mesh, uploaded on first use
  std::vector<std::shared_ptr<const Mesh>> customKeep;  // so a key is never reused by a new mesh
  std::string fontPath;
  std::map<int, std::unique_ptr<Font>> fonts;  // by pixel size
  std::map<int, GLuint> atlases;
  FrameTimings* timings = nullptr;  // set while a timed frame is drawn
  std::chrono::steady_clock::time_point mark;

  // Timed frames: finishes the GL work so far and adds the time since the last lap to `slot`.
  void lap(double FrameTimings::*slot) {
    if (!timings) return;
    glFinish();
    const auto now = std::chrono::steady_clock::now();
    timings->*slot += std::chrono::duration<double>(now - mark).count();
    mark = now;
  }

  void makeCurrent() {
    if (!OSMesaMakeCurrent(ctx, dummy.data(), GL_UNSIGNED_BYTE, 4, 4)) throw RenderError("OSMesaMakeCurrent failed");
  }

  GpuMesh upload(const MeshData& m) {
    GpuMesh g;
    glGenVertexArrays(1, &g.vao);
    glBindVertexArray(g.vao);
    glGenBuffers(1, &g.vbo);
    glBindBuffer(GL_ARRAY_BUFFER, g.vbo);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(m.vertices.size() * sizeof(MeshVertex)), m.vertices.data(),
                 GL_STATIC_DRAW);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(MeshVertex), reinterpret_cast<void*>(offsetof(MeshVertex, position)));
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, sizeof(MeshVertex), reinterpret_cast<void*>(offsetof(MeshVertex, normal)));
    glEnableVertexAttribArray(2);
    glVertexAttribPointer(2, 1, GL_FLOAT, GL_FALSE, sizeof(MeshVertex), reinterpret_cast<void*>(offsetof(MeshVertex, capSign)));
    glGenBuffers(1, &g.ebo);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, g.ebo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(m.indices.size() * sizeof(uint32_t)), m.indices.data(),
                 GL_STATIC_DRAW);
    g.count = static_cast<GLsizei>(m.indices.size());
    // Instance attributes come from the shared instance buffer; pointers are set per draw.
    glBindBuffer(GL_ARRAY_BUFFER, instanceVbo);
    for (GLuint loc = 3; loc <= 6; ++loc) {
      glEnableVertexAttribArray(loc);
      glVertexAttribDivisor(loc, 1);
    }
    glBindVertexArray(0);
    return g;
  }

  const GpuMesh& meshFor(int id, int level, const DrawList& dl) {
    if (id < kFirstCustomMesh) return primitives[static_cast<size_t>(id)][static_cast<size_t>(isRound(id) ? level : 0)];
    const auto& sp = dl.meshes.at(static_cast<size_t>(id - kFirstCustomMesh));
    auto it = custom.find(sp.get());
    if (it != custom.end()) return it->second;
    customKeep.push_back(sp);
    return custom.emplace(sp.get(), upload(modelMesh(*sp))).first->second;
  }

  Font& font(int px) {
    auto it = fonts.find(px);
    if (it != fonts.end()) return *it->second;
    auto f = std::make_unique<Font>(fontPath, static_cast<float>(px));
    GLuint tex;
    glGenTextures(1, &tex);
    glBindTexture(GL_TEXTURE_2D, tex);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_R8, f->atlasWidth(), f->atlasHeight(), 0, GL_RED, GL_UNSIGNED_BYTE, f->atlas().data());
    // Glyphs are placed on whole pixels, so nearest sampling reproduces the rasterised coverage exactly.
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    atlases[px] = tex;
    return *fonts.emplace(px, std::move(f)).first->second;
  }

  // Draws instances grouped by mesh and level of detail with one instanced call per group.
  // Within a group, nearest first: hidden fragments then fail the depth test early.
  // The instances with none of the `skip` flags and all of the `need` flags. With `finest`, no
  // instance is drawn finer than that scale would draw it.
  void drawInstances(const std::vector<Instance>& all, const DrawList& dl, uint32_t skip, uint32_t need,
                     const PixelScale& scale, const PixelScale* finest = nullptr) {
    struct Item {
      const Instance* in;
      int level;
      float distance;
    };
    std::vector<Item> list;
    list.reserve(all.size());
    for (const Instance& in : all)
      if (!(in.flags & skip) && (in.flags & need) == need)
        list.push_back({&in, finest ? std::min(levelOf(in, scale), levelOf(in, *finest)) : levelOf(in, scale),
                        (in.position - scale.eye).squaredNorm()});
    if (list.empty()) return;
    std::stable_sort(list.begin(), list.end(), [](const Item& a, const Item& b) {
      if (a.in->mesh != b.in->mesh) return a.in->mesh < b.in->mesh;
      if (a.level != b.level) return a.level < b.level;
      return a.distance < b.distance;
    });
    std::vector<GpuInstance> packed(list.size());
    for (size_t i = 0; i < list.size(); ++i) packed[i] = pack(*list[i].in);
    glBindBuffer(GL_ARRAY_BUFFER, instanceVbo);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(packed.size() * sizeof(GpuInstance)), packed.data(),
                 GL_STREAM_DRAW);
    for (size_t first = 0; first < list.size();) {
      const int mesh = list[first].in->mesh, level = list[first].level;
      size_t last = first;
      while (last < list.size() && list[last].in->mesh == mesh && list[last].level == level) ++last;
      const GpuMesh& m = meshFor(mesh, level, dl);
      // Primitives are closed and wound outwards, so their back faces need not be drawn (llvmpipe
      // pays per fragment, hidden or not); model meshes may be open (a bowl) and stay two-sided.
      if (mesh < kFirstCustomMesh)
        glEnable(GL_CULL_FACE);
      else
        glDisable(GL_CULL_FACE);
      glBindVertexArray(m.vao);
      const size_t base = first * sizeof(GpuInstance);
      for (GLuint k = 0; k < 4; ++k)
        glVertexAttribPointer(3 + k, 4, GL_FLOAT, GL_FALSE, sizeof(GpuInstance),
                              reinterpret_cast<void*>(base + k * 4 * sizeof(float)));
      glDrawElementsInstanced(GL_TRIANGLES, m.count, GL_UNSIGNED_INT, nullptr, static_cast<GLsizei>(last - first));
      first = last;
    }
    glBindVertexArray(0);
  }

  // The light's view and orthographic projection around the shadow bounds, snapped to whole
  // texels and to steps in size so shadows do not shimmer while bodies move.
  Mat4f lightMatrix(const DrawList& dl, float& texelWorld) const {
    const float radius = std::pow(1.15f, std::ceil(std::log(std::max(dl.boundsRadius, 0.25f)) / std::log(1.15f)));
    texelWorld = 2 * radius / static_cast<float>(shadowSize);
    const Vec3f dir = dl.lightDirection.normalized();
    Vec3f up = std::abs(dir.y()) > 0.99f ? Vec3f::UnitZ() : Vec3f::UnitY();
    const Vec3f s = dir.cross(up).normalized(), u = s.cross(dir);
    Mat4f view = Mat4f::Identity();
    view.block<1, 3>(0, 0) = s.transpose();
    view.block<1, 3>(1, 0) = u.transpose();
    view.block<1, 3>(2, 0) = -dir.transpose();
    // Light-space centre, snapped to the texel grid.
    Vec3f c(s.dot(dl.boundsCentre), u.dot(dl.boundsCentre), -dir.dot(dl.boundsCentre));
    c.x() = std::round(c.x() / texelWorld) * texelWorld;
    c.y() = std::round(c.y() / texelWorld) * texelWorld;
    view(0, 3) = -c.x();
    view(1, 3) = -c.y();
    view(2, 3) = -c.z();
    // Depth from 2 radii towards the light to far below: receivers beyond the casters' bounds still count.
    const float zn = -2 * radius, zf = 2 * radius + std::max(4 * radius, 50.0f);
    Mat4f ortho = Mat4f::Identity();
    ortho(0, 0) = 1 / radius;
    ortho(1, 1) = 1 / radius;
    // View space looks down -z; a point at depth d (z = -d) maps to [-1, 1] over [zn, zf].
    ortho(2, 2) = -2 / (zf - zn);
    ortho(2, 3) = -(zf + zn) / (zf - zn);
    return ortho * view;
  }

  // The view's shadow map, made on first use (texture unit 0 when drawing the scene).
  const ShadowMap& shadowMap(size_t view) {
    while (shadowMaps.size() <= view) {
      ShadowMap sm;
      glGenTextures(1, &sm.tex);
      glBindTexture(GL_TEXTURE_2D, sm.tex);
      const int side = std::max(shadowSize, 1);
      // 16-bit depth: the lookup's four gathers stalled on a 4 MB map (24 bits kept in 32), half
      // of it stays in the cache better; 1/65536 of the light's depth range (about 1 mm at 60 m)
      // is below the polygon offset and the normal bias.
      glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT16, side, side, 0, GL_DEPTH_COMPONENT, GL_UNSIGNED_SHORT, nullptr);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_MODE, GL_COMPARE_REF_TO_TEXTURE);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_FUNC, GL_LEQUAL);
      if (shadowSize > 0) {
        glGenFramebuffers(1, &sm.fbo);
        glBindFramebuffer(GL_FRAMEBUFFER, sm.fbo);
        glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, sm.tex, 0);
        glDrawBuffer(GL_NONE);
        glReadBuffer(GL_NONE);
        if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
          throw RenderError("GL: the shadow map buffer is incomplete");
      }
      shadowMaps.push_back(sm);
    }
    return shadowMaps[view];
  }

  // Depth of the view's shadow casters from the light.
  void drawShadowMap(const DrawList& dl, const Viewport& vp, const ShadowMap& sm) {
    float texelWorld = 0;
    const Mat4f light = lightMatrix(dl, texelWorld);
    glBindFramebuffer(GL_FRAMEBUFFER, sm.fbo);
    glViewport(0, 0, shadowSize, shadowSize);
    glDisable(GL_SCISSOR_TEST);
    glEnable(GL_DEPTH_TEST);
    glDepthMask(GL_TRUE);
    glClear(GL_DEPTH_BUFFER_BIT);
    glEnable(GL_POLYGON_OFFSET_FILL);
    glPolygonOffset(1.5f, 2.0f);
    glUseProgram(depthProg);
    glUniformMatrix4fv(glGetUniformLocation(depthProg, "uViewProj"), 1, GL_FALSE, light.data());
    PixelScale texels;  // orthographic: texels of the map per metre
    texels.eye = dl.boundsCentre - 1000 * dl.lightDirection;
    texels.perMetre = 1 / texelWorld;
    texels.maxError = kMaxShadowSilhouetteError;
    // A caster finer than what receives its shadow would stand out of the receiver's facets and
    // shade their middles (acne): casters are never finer than the view draws them.
    const PixelScale screen = screenScale(dl, vp);
    drawInstances(dl.solids, dl, kNoShadow, 0, texels, &screen);
    glDisable(GL_POLYGON_OFFSET_FILL);
  }

  // The solids, the sky (unless it goes under them after the resolve) and the overlays of a view
  // into drawFbo, which is bound and was cleared for the whole frame.
  void drawScene(const DrawList& dl, const Viewport& vp, const ShadowMap& sm) {
    const float aspect = static_cast<float>(vp.width) / static_cast<float>(std::max(vp.height, 1));
    const Mat4f viewProj = dl.camera.projection(aspect) * dl.camera.view();
    float texelWorld = 0;
    const Mat4f light = lightMatrix(dl, texelWorld);
    const bool shadows = shadowSize > 0;
    const int glY = height - (vp.y + vp.height);  // GL counts rows from the bottom
    glViewport(vp.x, glY, vp.width, vp.height);
    // The scissor only matters for the overlays' depth clear in a panel of a grid.
    const bool whole = vp.x == 0 && vp.y == 0 && vp.width == width && vp.height == height;
    if (whole) {
      glDisable(GL_SCISSOR_TEST);
    } else {
      glScissor(vp.x, glY, vp.width, vp.height);
      glEnable(GL_SCISSOR_TEST);
    }
    glDepthMask(GL_TRUE);

    // Solids.
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, sm.tex);
    const float dist = (dl.camera.eye - dl.camera.target).norm();
    const float fog[2] = {std::max(3 * dist, 30.0f), std::max(12 * dist, 150.0f)};
    const Vec3f ld = dl.lightDirection.normalized();
    auto useLit = [&](GLuint prog) {
      glUseProgram(prog);
      glUniform1i(glGetUniformLocation(prog, "uShadowMap"), 0);
      glUniformMatrix4fv(glGetUniformLocation(prog, "uViewProj"), 1, GL_FALSE, viewProj.data());
      glUniformMatrix4fv(glGetUniformLocation(prog, "uLightMatrix"), 1, GL_FALSE, light.data());
      glUniform3fv(glGetUniformLocation(prog, "uEye"), 1, dl.camera.eye.data());
      glUniform3fv(glGetUniformLocation(prog, "uLightDir"), 1, ld.data());
      glUniform1f(glGetUniformLocation(prog, "uNormalBias"), 1.5f * texelWorld);
      glUniform3fv(glGetUniformLocation(prog, "uHorizon"), 1, kHorizon.data());
      glUniform2fv(glGetUniformLocation(prog, "uFog"), 1, fog);
    };
    const PixelScale pixels = screenScale(dl, vp);
    // The bodies, then the gridded statics (the ground) with the program that draws the grid:
    // llvmpipe would run the grid's code for every fragment of one program with a branch, and
    // ground drawn last is not shaded where bodies cover it.
    useLit(litProg[0][shadows]);
    drawInstances(dl.solids, dl, kGrid, 0, pixels);
    useLit(litProg[1][shadows]);
    drawInstances(dl.solids, dl, 0, kGrid, pixels);

    // The sky where no solid is: at the far plane, passing the depth test only where the depth
    // is still the cleared 1.
    if (!skyUnder) {
      glDisable(GL_CULL_FACE);
      glDepthFunc(GL_LEQUAL);
      glDepthMask(GL_FALSE);
      drawSky(dl, vp);
      glDepthFunc(GL_LESS);
      glDepthMask(GL_TRUE);
    }

    // Overlays show through the bodies (contacts lie between them), but not through each other.
    if (!dl.overlays.empty()) {
      glClear(GL_DEPTH_BUFFER_BIT);
      glUseProgram(flatProg);
      glUniformMatrix4fv(glGetUniformLocation(flatProg, "uViewProj"), 1, GL_FALSE, viewProj.data());
      glUniform3fv(glGetUniformLocation(flatProg, "uEye"), 1, dl.camera.eye.data());
      drawInstances(dl.overlays, dl, 0, 0, pixels);
    }
    glDisable(GL_SCISSOR_TEST);
  }

  // The sky over a view's viewport (depth and blending as the caller set them).
  void drawSky(const DrawList& dl, const Viewport& vp) {
    const float aspect = static_cast<float>(vp.width) / static_cast<float>(std::max(vp.height, 1));
    const Mat4f inv = (dl.camera.projection(aspect) * dl.camera.view()).inverse();
    glViewport(vp.x, height - (vp.y + vp.height), vp.width, vp.height);
    glUseProgram(skyProg);
    glUniformMatrix4fv(glGetUniformLocation(skyProg, "uInvViewProj"), 1, GL_FALSE, inv.data());
    glUniform3fv(glGetUniformLocation(skyProg, "uHorizon"), 1, kHorizon.data());
    glBindVertexArray(emptyVao);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glBindVertexArray(0);
  }

  // Text of one view: the HUD top left on a dark panel, the label top centre, the footer bottom left.
  void drawText(const DrawList& dl, const Viewport& vp) {
    const int px = std::clamp(static_cast<int>(std::lround(std::sqrt(double(vp.height) * height) / 36.0)), 11, 48);
    Font& small = font(px);
    const float pad = std::round(0.5f * px);
    std::vector<TextVertex> solid, glyphsSmall, glyphsLarge;
    auto rect = [this](std::vector<TextVertex>& v, float x0, float y0, float x1, float y1, const Vec4f& c) {
      // Text panels are sharp already: the anti-aliasing leaves them (and a pixel around) alone.
      textRects.push_back({static_cast<int>(std::floor(x0)) - 1, static_cast<int>(std::floor(y0)) - 1,
                           static_cast<int>(std::ceil(x1)) + 1, static_cast<int>(std::ceil(y1)) + 1});
      const TextVertex a{x0, y0, -1, -1, c[0], c[1], c[2], c[3]}, b{x1, y0, -1, -1, c[0], c[1], c[2], c[3]},
                       d{x1, y1, -1, -1, c[0], c[1], c[2], c[3]}, e{x0, y1, -1, -1, c[0], c[1], c[2], c[3]};
      v.insert(v.end(), {a, b, d, a, d, e});
    };
    auto glyphs = [](std::vector<TextVertex>& v, const Font& f, const std::string& s, float x, float base,
                     const Vec4f& c) {
      for (const GlyphQuad& q : f.layout(s, x, base)) {
        const TextVertex a{q.x0, q.y0, q.s0, q.t0, c[0], c[1], c[2], c[3]}, b{q.x1, q.y0, q.s1, q.t0, c[0], c[1], c[2], c[3]},
                         d{q.x1, q.y1, q.s1, q.t1, c[0], c[1], c[2], c[3]}, e{q.x0, q.y1, q.s0, q.t1, c[0], c[1], c[2], c[3]};
        v.insert(v.end(), {a, b, d, a, d, e});
      }
    };
    auto block = [&](const std::vector<TextLine>& lines, float x, float top) {
      if (lines.empty()) return;
      float w = 0;
      for (const TextLine& l : lines) w = std::max(w, small.width(l.text));
      const float h = lines.size() * small.lineHeight();
      rect(solid, x, top, x + w + 2 * pad, top + h + 2 * pad, Vec4f(0.05f, 0.06f, 0.08f, 0.62f));
      float base = top + pad + small.ascent();
      for (const TextLine& l : lines) {
        glyphs(glyphsSmall, small, l.text, x + pad, base, l.colour);
        base += small.lineHeight();
      }
    };
    const float margin = std::round(0.6f * px);
    float hudTop = vp.y + margin;
    Font* large = nullptr;
    if (!dl.label.empty()) {
      // The label heads the panel, centred; the HUD goes under it so narrow panels do not overlap.
      large = &font(static_cast<int>(std::lround(px * 1.5)));
      const float w = large->width(dl.label);
      const float x = std::round(vp.x + 0.5f * (vp.width - w));
      rect(solid, x - pad, hudTop, x + w + pad, hudTop + large->lineHeight() + pad, Vec4f(0.05f, 0.06f, 0.08f, 0.7f));
      glyphs(glyphsLarge, *large, dl.label, x, hudTop + 0.5f * pad + large->ascent(), dl.labelColour);
      hudTop += large->lineHeight() + pad + margin;
    }
    block(dl.hud, vp.x + margin, hudTop);
    block(dl.footer, vp.x + margin,
          vp.y + vp.height - margin - 2 * pad - dl.footer.size() * small.lineHeight());
    // Panel borders in a grid: a one-pixel dark line on the right and bottom edges.
    if (vp.width < width) rect(solid, vp.x + vp.width - 1, vp.y, vp.x + vp.width, vp.y + vp.height, Vec4f(0, 0, 0, 1));
    if (vp.height < height) rect(solid, vp.x, vp.y + vp.height - 1, vp.x + vp.width, vp.y + vp.height, Vec4f(0, 0, 0, 1));

    glUseProgram(textProg);
    const float frame[2] = {static_cast<float>(width), static_cast<float>(height)};
    glUniform2fv(glGetUniformLocation(textProg, "uFrame"), 1, frame);
    glUniform1i(glGetUniformLocation(textProg, "uAtlas"), 0);
    glActiveTexture(GL_TEXTURE0);
    glBindVertexArray(textVao);
    glBindBuffer(GL_ARRAY_BUFFER, textVbo);
    auto draw = [&](const std::vector<TextVertex>& v, GLuint atlas) {
      if (v.empty()) return;
      glBindTexture(GL_TEXTURE_2D, atlas);
      glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(v.size() * sizeof(TextVertex)), v.data(), GL_STREAM_DRAW);
      glDrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(v.size()));
    };
    draw(solid, atlases[px]);
    draw(glyphsSmall, atlases[px]);
    if (large) draw(glyphsLarge, atlases[static_cast<int>(std::lround(px * 1.5))]);
    glBindVertexArray(0);
  }
};

GlRenderer::GlRenderer(int width, int height, const RendererOptions& options)
    : impl_(std::make_unique<Impl>()), width_(width), height_(height) {
  if (width <= 0 || height <= 0) throw RenderError("frame size must be positive");
  setenv("LP_NUM_THREADS", "2", 0);  // llvmpipe reads it when the first context is made
  Impl& m = *impl_;
  m.width = width;
  m.height = height;
  m.fontPath = options.fontPath.empty() ? defaultFontPath() : options.fontPath;
  const int attribs[] = {OSMESA_FORMAT, OSMESA_RGBA, OSMESA_DEPTH_BITS, 0, OSMESA_STENCIL_BITS, 0,
                         OSMESA_PROFILE, OSMESA_CORE_PROFILE, OSMESA_CONTEXT_MAJOR_VERSION, 3,
                         OSMESA_CONTEXT_MINOR_VERSION, 3, 0};
  m.ctx = OSMesaCreateContextAttribs(attribs, nullptr);
  if (!m.ctx) throw RenderError("OSMesa could not create a GL 3.3 core context (is libosmesa6 installed?)");
  m.dummy.assign(4 * 4 * 4, 0);
  m.makeCurrent();

  GLint maxSamples = 1, maxSize = 0;
  glGetIntegerv(GL_MAX_SAMPLES, &maxSamples);
  glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &maxSize);
  if (width > maxSize || height > maxSize)
    throw RenderError("frame " + std::to_string(width) + "x" + std::to_string(height) + " exceeds the GL limit " +
                      std::to_string(maxSize));
  m.samples = std::clamp(options.samples, 1, std::max(1, maxSamples));
  m.shadowSize = std::clamp(options.shadowSize, 0, static_cast<int>(maxSize));

  auto renderbuffer = [&](GLenum format, int samples) {
    GLuint rb;
    glGenRenderbuffers(1, &rb);
    glBindRenderbuffer(GL_RENDERBUFFER, rb);
    if (samples > 0)
      glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples, format, width, height);
    else
      glRenderbufferStorage(GL_RENDERBUFFER, format, width, height);
    return rb;
  };
  m.antiAliasing = options.antiAliasing;
  auto complete = [](const char* what) {
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw RenderError(std::string("GL: the ") + what + " buffer is incomplete");
  };
  // The frame that gets the text and is read back; without multisampling the scene is drawn
  // into it directly.
  glGenFramebuffers(1, &m.sceneFbo);
  glBindFramebuffer(GL_FRAMEBUFFER, m.sceneFbo);
  m.sceneColour = renderbuffer(GL_RGBA8, 0);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, m.sceneColour);
  if (m.samples > 1) {
    complete("output");
    glGenFramebuffers(1, &m.msFbo);
    glBindFramebuffer(GL_FRAMEBUFFER, m.msFbo);
    m.msColour = renderbuffer(GL_RGBA8, m.samples);
    GLint actual = m.samples;  // what the driver made of the request (llvmpipe: 4 for any count above 1)
    glGetRenderbufferParameteriv(GL_RENDERBUFFER, GL_RENDERBUFFER_SAMPLES, &actual);
    m.samples = std::max<int>(actual, 2);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, m.msColour);
    m.msDepth = renderbuffer(GL_DEPTH_COMPONENT24, m.samples);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, m.msDepth);
    complete("multisampled scene");
    m.drawFbo = m.msFbo;
  } else {
    m.sceneDepth = renderbuffer(GL_DEPTH_COMPONENT24, 0);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, m.sceneDepth);
    complete("scene");
    m.drawFbo = m.sceneFbo;
  }
  m.shadowMap(0);

  m.skyUnder = m.samples > 1 && m.antiAliasing == AntiAliasing::None;
  const std::string header =
      std::string("#version 330 core\n#define COVERAGE_ALPHA ") + (m.skyUnder ? "1" : "0") + "\n";
  auto meshVariant = [&](int mode, bool grid, bool shadow) {
    return header + "#define MODE " + std::to_string(mode) + "\n#define GRID " + (grid ? "1" : "0") +
           "\n#define SHADOW " + (shadow ? "1" : "0") + "\n" + kMeshFS;
  };
  for (int grid = 0; grid < 2; ++grid)
    for (int shadow = 0; shadow < 2; ++shadow)
      m.litProg[grid][shadow] = link(kMeshVS, meshVariant(0, grid, shadow).c_str(), grid ? "gridded mesh" : "mesh");
  m.flatProg = link(kMeshVS, meshVariant(1, false, false).c_str(), "overlay");
  m.depthProg = link(kMeshVS, meshVariant(2, false, false).c_str(), "shadow");
  m.skyProg = link(kSkyVS, (header + kSkyFS).c_str(), "sky");
  m.textProg = link(kTextVS, kTextFS, "text");

  glGenBuffers(1, &m.instanceVbo);
  glGenVertexArrays(1, &m.emptyVao);
  for (int id = 0; id < kFirstCustomMesh; ++id) {
    m.primitives.emplace_back();
    for (int level = 0; level < (isRound(id) ? kRoundLevels : 1); ++level)
      m.primitives.back().push_back(m.upload(primitiveMesh(id, level)));
  }

  glGenVertexArrays(1, &m.textVao);
  glBindVertexArray(m.textVao);
  glGenBuffers(1, &m.textVbo);
  glBindBuffer(GL_ARRAY_BUFFER, m.textVbo);
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, sizeof(TextVertex), reinterpret_cast<void*>(offsetof(TextVertex, x)));
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, sizeof(TextVertex), reinterpret_cast<void*>(offsetof(TextVertex, s)));
  glEnableVertexAttribArray(2);
  glVertexAttribPointer(2, 4, GL_FLOAT, GL_FALSE, sizeof(TextVertex), reinterpret_cast<void*>(offsetof(TextVertex, r)));
  glBindVertexArray(0);

  try {
    m.font(12);  // fail now, with the font's name, rather than at the first frame
  } catch (const std::exception& e) {
    throw RenderError(e.what());
  }
  if (const GLenum err = glGetError(); err != GL_NO_ERROR)
    throw RenderError("GL error " + std::to_string(err) + " while setting up the renderer");
}

GlRenderer::~GlRenderer() {
  if (!impl_ || !impl_->ctx) return;
  // Unbind first: OSMesa frees the buffer it made for MakeCurrent only when it stops being
  // current (else LeakSanitizer reports it). Destroying the context frees every GL object.
  if (OSMesaGetCurrentContext() == impl_->ctx) OSMesaMakeCurrent(nullptr, nullptr, GL_UNSIGNED_BYTE, 0, 0);
  OSMesaDestroyContext(impl_->ctx);
}

std::string GlRenderer::glInfo() const {
  impl_->makeCurrent();
  const auto* r = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  const auto* v = reinterpret_cast<const char*>(glGetString(GL_VERSION));
  std::string aa = impl_->samples > 1 ? std::to_string(impl_->samples) + "x MSAA" : std::string();
  if (impl_->antiAliasing == AntiAliasing::Fxaa) aa += aa.empty() ? "FXAA" : " + FXAA";
  return std::string(r ? r : "?") + ", GL " + (v ? v : "?") + ", " + (aa.empty() ? "no anti-aliasing" : aa);
}

Image GlRenderer::render(const DrawList& list) { return render({View{&list, Viewport{0, 0, width_, height_}}}); }

Image GlRenderer::render(const std::vector<View>& views) {
  Image img;
  render(views, img);
  return img;
}

void GlRenderer::render(const std::vector<View>& views, Image& img, FrameTimings* timings) {
  Impl& m = *impl_;
  draw(views, m.raw, timings);
  const auto t0 = std::chrono::steady_clock::now();
  const FxaaStats st = finishFrame(m.raw, img);
  if (timings) {
    timings->antiAliasing = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    timings->blendedPixels = st.edgePixels;
  }
}

void GlRenderer::draw(const std::vector<View>& views, RawFrame& out, FrameTimings* timings) {
  Impl& m = *impl_;
  m.makeCurrent();
  m.timings = timings;
  if (timings) {
    *timings = FrameTimings{};
    glFinish();
    m.mark = std::chrono::steady_clock::now();
  }
  glDisable(GL_BLEND);
  // Shadow maps first, one per view: llvmpipe draws a frame buffer's work when another is bound,
  // so a clear followed by a switch to the shadow map would be a real pass over the buffer, while
  // a clear followed by drawing is done per tile as it is drawn (next to free).
  if (m.shadowSize > 0)
    for (size_t i = 0; i < views.size(); ++i) m.drawShadowMap(*views[i].list, views[i].viewport, m.shadowMap(i));
  m.lap(&FrameTimings::shadow);
  // One clear of the whole surface (colour and depth) for every view: panels do not overlap. The
  // sky then covers what the solids leave; drawn under them after the resolve, it needs the
  // alpha cleared to 0 (nothing covered).
  glBindFramebuffer(GL_FRAMEBUFFER, m.drawFbo);
  glDisable(GL_SCISSOR_TEST);
  glViewport(0, 0, width_, height_);
  glClearColor(0, 0, 0, m.skyUnder ? 0.0f : 1.0f);
  glClearDepth(1.0);
  glDepthMask(GL_TRUE);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  for (size_t i = 0; i < views.size(); ++i) m.drawScene(*views[i].list, views[i].viewport, m.shadowMap(i));
  m.lap(&FrameTimings::scene);

  if (m.samples > 1) {
    glBindFramebuffer(GL_READ_FRAMEBUFFER, m.msFbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, m.sceneFbo);
    glBlitFramebuffer(0, 0, width_, height_, 0, 0, width_, height_, GL_COLOR_BUFFER_BIT, GL_NEAREST);
  }
  glBindFramebuffer(GL_FRAMEBUFFER, m.sceneFbo);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_CULL_FACE);
  glDisable(GL_SCISSOR_TEST);
  glEnable(GL_BLEND);
  if (m.skyUnder) {
    glBlendFunc(GL_ONE_MINUS_DST_ALPHA, GL_ONE);  // the sky under what is there; alpha ends at 1
    for (const View& v : views) m.drawSky(*v.list, v.viewport);
  }
  if (m.samples > 1) m.lap(&FrameTimings::resolve);
  glViewport(0, 0, width_, height_);
  glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ZERO, GL_ONE);
  m.textRects.clear();
  for (const View& v : views) m.drawText(*v.list, v.viewport);
  glDisable(GL_BLEND);
  m.lap(&FrameTimings::text);

  out.width = width_;
  out.height = height_;
  out.rgba.resize(static_cast<size_t>(width_) * 4 * static_cast<size_t>(height_));
  glBindFramebuffer(GL_READ_FRAMEBUFFER, m.sceneFbo);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, width_, height_, GL_RGBA, GL_UNSIGNED_BYTE, out.rgba.data());
  if (const GLenum err = glGetError(); err != GL_NO_ERROR) throw RenderError("GL error " + std::to_string(err) + " while drawing");
  out.keep = m.textRects;
  out.fxaa = m.antiAliasing == AntiAliasing::Fxaa;
  m.lap(&FrameTimings::readback);
  m.timings = nullptr;
}

std::optional<AntiAliasing> parseAntiAliasing(const std::string& s) {
  if (s == "none") return AntiAliasing::None;
  if (s == "fxaa") return AntiAliasing::Fxaa;
  return std::nullopt;
}

const char* antiAliasingName(AntiAliasing a) { return a == AntiAliasing::Fxaa ? "fxaa" : "none"; }

std::vector<Viewport> gridLayout(int width, int height, int panels) {
  const int cols = panels <= 1 ? 1 : 2, rows = panels <= 2 ? 1 : 2;
  std::vector<Viewport> out;
  for (int i = 0; i < panels; ++i) {
    const int c = i % cols, r = i / cols;
    const int x0 = width * c / cols, x1 = width * (c + 1) / cols;
    const int y0 = height * r / rows, y1 = height * (r + 1) / rows;
    out.push_back({x0, y0, x1 - x0, y1 - y0});
  }
  return out;
}

}  // namespace substep::render
