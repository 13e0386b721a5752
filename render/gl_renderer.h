// The GL backend: owns an OSMesa context (llvmpipe, core profile, no display, no GPU) and draws
// draw lists off-screen: instanced meshes, per-pixel lighting, a shadow map from the one
// directional light, a gridded ground, the sky, overlays and text, anti-aliased by a post-process
// edge blend (render/fxaa.h) or by multisampling.
#pragma once

#include "render/draw_list.h"
#include "render/fxaa.h"
#include "render/image.h"

#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace substep::render {

// Anti-aliasing by a post-process filter on the finished frame (on top of any multisampling).
enum class AntiAliasing {
  None,  // multisampling only (RendererOptions::samples), or none
  Fxaa,  // FXAA 3.11's edge search and blend on the read-back frame, on the CPU (render/fxaa.h)
};
std::optional<AntiAliasing> parseAntiAliasing(const std::string& s);  // "none", "fxaa"
const char* antiAliasingName(AntiAliasing a);

// The default is FXAA without multisampling, the cheaper of the two on llvmpipe for the same edges
// (docs/rendering.md, "Measured").
struct RendererOptions {
  AntiAliasing antiAliasing = AntiAliasing::Fxaa;
  int samples = 1;           // multisampling; 1 turns it off; llvmpipe makes any other count 4 (its only one)
  int shadowSize = 1024;     // shadow map side [texels]; 0 turns shadows off
  std::string fontPath;      // empty: defaultFontPath()
};

// A rectangle of the frame in pixels, (x, y) its top-left corner.
struct Viewport {
  int x = 0, y = 0, width = 0, height = 0;
};

struct View {
  const DrawList* list = nullptr;
  Viewport viewport;
};

// Where a frame's time went [s], when render() is asked for it: each stage ends with glFinish,
// so the stages no longer overlap and their sum differs a little from an untimed frame.
struct FrameTimings {
  double shadow = 0;        // shadow map pass(es)
  double scene = 0;         // solids, sky, overlays
  double resolve = 0;       // multisample resolve (a blit) and, without FXAA, the sky under it
  double text = 0;          // HUD, labels, legend
  double readback = 0;      // glReadPixels
  double antiAliasing = 0;  // the post-process filter with the row flip (the flip alone without it), on the CPU
  long long blendedPixels = 0;  // pixels the post-process filter changed
  double total() const { return shadow + scene + resolve + text + readback + antiAliasing; }
};

class RenderError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class GlRenderer {
 public:
  // Creates the context and the frame's buffers. Sets LP_NUM_THREADS=2 when unset (the fastest on
  // two cores, measured). Throws RenderError when OSMesa or the font fails.
  GlRenderer(int width, int height, const RendererOptions& options = {});
  ~GlRenderer();
  GlRenderer(const GlRenderer&) = delete;
  GlRenderer& operator=(const GlRenderer&) = delete;

  int width() const { return width_; }
  int height() const { return height_; }
  std::string glInfo() const;  // renderer and version strings, and the anti-aliasing

  // Draws every view into its viewport (a grid of comparison panels, or one view filling the
  // frame), then its text; returns the frame, row 0 at the top.
  Image render(const std::vector<View>& views);
  Image render(const DrawList& list);
  // The same into `out`, reusing its pixels when the size matches (no page faults per frame).
  // With `timings`, every stage is finished and timed (for benchmarks; slower).
  void render(const std::vector<View>& views, Image& out, FrameTimings* timings = nullptr);
  // The GL part alone: the frame read back, before the anti-aliasing filter and the row flip,
  // which finishFrame() (render/fxaa.h) does on any thread: render() is draw() then finishFrame().
  void draw(const std::vector<View>& views, RawFrame& out, FrameTimings* timings = nullptr);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int width_, height_;
};

// Panels of a comparison grid: 1 fills the frame, 2 side by side, 3-4 in two rows.
std::vector<Viewport> gridLayout(int width, int height, int panels);

}  // namespace substep::render
