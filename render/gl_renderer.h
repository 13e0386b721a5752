// The GL backend: owns an OSMesa context (llvmpipe, core profile, no display, no GPU) and draws
// draw lists into an off-screen multisampled framebuffer: instanced meshes, per-pixel lighting,
// a shadow map from the one directional light, a gridded ground, overlays and text.
#pragma once

#include "render/draw_list.h"
#include "render/image.h"

#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace substep::render {

struct RendererOptions {
  int samples = 4;           // multisampling; clamped to what the context offers; 1 turns it off
  int shadowSize = 1024;     // shadow map side [texels]; 0 turns shadows off (2048 costs 2.5 ms more at 720p)
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
  std::string glInfo() const;  // renderer and version strings

  // Draws every view into its viewport (a grid of comparison panels, or one view filling the
  // frame), then its text; returns the frame, row 0 at the top.
  Image render(const std::vector<View>& views);
  Image render(const DrawList& list);
  // The same into `out`, reusing its pixels when the size matches (no page faults per frame).
  void render(const std::vector<View>& views, Image& out);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int width_, height_;
};

// Panels of a comparison grid: 1 fills the frame, 2 side by side, 3-4 in two rows.
std::vector<Viewport> gridLayout(int width, int height, int panels);

}  // namespace substep::render
