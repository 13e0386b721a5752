// Post-process anti-aliasing of a finished frame on the CPU: the edge search and blend of Timothy
// Lottes' FXAA 3.11 ("quality" variant), run only on the pixels of the read-back frame whose
// local contrast is an edge's. The renderer's shaders leave each pixel's luma in its alpha, so
// finding those pixels reads one byte a pixel. See docs/rendering.md for why this runs on the CPU
// rather than in a full-screen shader on llvmpipe.
#pragma once

#include "render/image.h"

#include <cstdint>
#include <vector>

namespace substep::render {

struct PixelRect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // [x0, x1) x [y0, y1), rows counted from the top
};

// The alpha the shaders write: luma (Rec. 601, 0 to 127) in bits 1-7, bit 0 set where the pixel
// is smooth by construction (the sky; the ground, whose grid lines are anti-aliased as drawn).
inline uint8_t encodeLumaAlpha(float luma, bool smooth) {
  const float l = luma < 0 ? 0 : (luma > 1 ? 1 : luma);
  return static_cast<uint8_t>(2 * static_cast<int>(l * 127 + 0.5f) + (smooth ? 1 : 0));
}

struct FxaaOptions {
  float edgeThreshold = 0.125f;     // contrast, as a share of the brightest of the pixel and its 4 neighbours, of an edge
  float edgeThresholdMin = 0.0625f; // and at least this (dark regions)
  float subpix = 0.75f;             // how strongly single-pixel features are softened, 0 to 1
};

struct FxaaStats {
  long long edgePixels = 0;  // pixels that were blended
};

// Writes `dst` (width x height, row 0 at the top, alpha 255) from `src`, RGBA with the luma alpha
// above, whose row y (counted from the top) starts at src + y * srcStride bytes (a negative
// stride reads GL's bottom-up rows). A pixel is blended with its neighbour across an edge when
// the contrast of it and its four neighbours is an edge's and not all five are smooth: by how
// near the edge's end it lies (FXAA's search along the edge, up to 34 pixels each way) or by how
// much it stands out (FXAA's sub-pixel term). Other pixels, and those inside `keep` (text), are
// copied.
FxaaStats fxaa(const uint8_t* src, long srcStride, int width, int height, Image& dst,
               const std::vector<PixelRect>& keep = {}, const FxaaOptions& options = {});

// The same frame without anti-aliasing: copied (flipped by a negative stride), alpha 255.
void copyOpaque(const uint8_t* src, long srcStride, int width, int height, Image& dst);

// A frame as the renderer reads it back (GlRenderer::draw): rows bottom-up, the luma in the
// alpha, with what the filter must leave alone and whether to filter. finishFrame() makes the
// image of it; it needs no GL context, so it can run on another thread while the next frame is
// drawn.
struct RawFrame {
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;   // width * height * 4, row 0 at the bottom
  std::vector<PixelRect> keep; // text panels (rows counted from the top)
  bool fxaa = true;            // the filter, else a plain copy
};
// Filtered (or copied), flipped, opaque: the frame as GlRenderer::render returns it.
FxaaStats finishFrame(const RawFrame& frame, Image& out);
// The same filter on the frame itself, for what reads its colours through a stride (the video's
// conversion): the pixels blended as finishFrame blends them, the rows left bottom-up and the
// alpha the luma. A frame without the filter is left as it is.
FxaaStats finishInPlace(RawFrame& frame);

}  // namespace substep::render
