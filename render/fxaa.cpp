#include "render/fxaa.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>

namespace substep::render {

namespace {

// Steps of the edge-end search after the first (pixels along the edge), lengthening as FXAA's
// quality presets do: up to 34 pixels each way.
constexpr int kSearchSteps[] = {1, 1, 1, 2, 2, 2, 4, 8, 12};
constexpr int kSearchReach = 1 + 1 + 1 + 1 + 2 + 2 + 2 + 4 + 8 + 12;

// A row's pixels made opaque: the alpha held the luma. Pixels as 32-bit words, alpha the high
// byte (little-endian), so the loop vectorises.
static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "RGBA as little-endian words");
void opaqueRow(const uint8_t* __restrict in, uint8_t* __restrict out, int width) {
  for (int x = 0; x < width; ++x) {
    uint32_t p;
    std::memcpy(&p, in + 4 * x, 4);
    p |= 0xff000000u;
    std::memcpy(out + 4 * x, &p, 4);
  }
}

// The alpha bytes of a row, with the end pixels repeated on either side: a[-1] .. a[width].
void alphaRow(const uint8_t* __restrict in, uint8_t* __restrict a, int width) {
  for (int x = 0; x < width; ++x) a[x] = in[4 * x + 3];
  a[-1] = a[0];
  a[width] = a[width - 1];
}

// Marks the pixels of a row whose contrast with their four neighbours is an edge's (on the luma
// in bits 1-7 of the alpha) and that are not smooth along with all four (bit 0). Returns whether
// any is. In 16-bit lanes (range and hi times 256 stay below 2^15), so it vectorises 8 wide.
bool edgeRow(const uint8_t* __restrict up, const uint8_t* __restrict mid, const uint8_t* __restrict down,
             uint8_t* __restrict edge, int width, int minRange, int share256) {
  uint8_t any = 0;
  for (int x = 0; x < width; ++x) {
    const uint8_t n = up[x], s = down[x], w = mid[x - 1], e = mid[x + 1], m = mid[x];
    const uint16_t hi = std::max(std::max(std::max(n, s), std::max(w, e)), m) >> 1;
    const uint16_t lo = std::min(std::min(std::min(n, s), std::min(w, e)), m) >> 1;
    const uint16_t range = static_cast<uint16_t>(hi - lo);
    const uint8_t smooth = n & s & w & e & m & 1;
    const uint8_t on = (range >= minRange) & (static_cast<uint16_t>(range << 8) >= static_cast<uint16_t>(hi * share256)) &
                       (smooth ^ 1);
    edge[x] = on;
    any |= on;
  }
  return any != 0;
}

}  // namespace

void copyOpaque(const uint8_t* src, long srcStride, int width, int height, Image& dst) {
  if (dst.width != width || dst.height != height) dst = Image(width, height);
  for (int y = 0; y < height; ++y)
    opaqueRow(src + static_cast<long>(y) * srcStride, &dst.rgba[static_cast<size_t>(y) * width * 4], width);
}

namespace {

// The filter, reading `src` only: onRow(y, row) for each row before its pixels, onBlend(y, x, rgb)
// for each pixel blended (the pixel of row y counted from the top, its three new channels).
template <class OnRow, class OnBlend>
FxaaStats filter(const uint8_t* src, long srcStride, int width, int height, const std::vector<PixelRect>& keep,
                 const FxaaOptions& options, OnRow onRow, OnBlend onBlend) {
  FxaaStats stats;
  if (width <= 0 || height <= 0) return stats;
  const int W = width, H = height;
  auto row = [&](int y) { return src + static_cast<long>(y) * srcStride; };
  // The alpha of every pixel, a byte each, with a pixel of margin either side of a row (the end
  // pixels repeated): the edge test and the search along edges read this plane, a quarter of the
  // frame's bytes (a search across rows stays in the cache).
  thread_local std::vector<uint8_t> plane, edges;
  const size_t P = static_cast<size_t>(W) + 2;
  plane.resize(P * static_cast<size_t>(H));
  edges.resize(static_cast<size_t>(W) + 8);
  // Filled a little ahead of the rows being filtered (the search reaches kSearchReach rows
  // down), so each row of the frame is read while it is still in the cache.
  int filled = 0;
  auto fillTo = [&](int y) {
    for (; filled < std::min(y, H); ++filled) alphaRow(row(filled), &plane[static_cast<size_t>(filled) * P + 1], W);
  };
  auto alphas = [&](int y) { return &plane[static_cast<size_t>(y) * P + 1]; };
  auto L = [&](int x, int y) { return static_cast<int>(alphas(y)[x] >> 1); };  // luma 0-127
  uint8_t* const edge = edges.data();

  const int minRange = static_cast<int>(std::ceil(options.edgeThresholdMin * 127));
  const int share256 = static_cast<int>(std::lround(options.edgeThreshold * 256));

  for (int y = 0; y < H; ++y) {
    fillTo(y + kSearchReach + 2);
    const uint8_t* in = row(y);
    onRow(y, in);
    if (!edgeRow(alphas(std::max(y - 1, 0)), alphas(y), alphas(std::min(y + 1, H - 1)), edge, W, minRange, share256))
      continue;
    for (const PixelRect& r : keep)
      if (y >= r.y0 && y < r.y1)
        for (int x = std::max(r.x0, 0); x < std::min(r.x1, W); ++x) edge[x] = 0;

    for (int x = 0; x < W; ++x) {
      if ((x & 7) == 0) {  // most of a row is not an edge: skip 8 at a time (edges has 8 bytes of slack)
        uint64_t eight;
        std::memcpy(&eight, edge + x, 8);
        if (x + 8 <= W && eight == 0) {
          x += 7;
          continue;
        }
      }
      if (!edge[x]) continue;
      const int xl = std::max(x - 1, 0), xr = std::min(x + 1, W - 1), yu = std::max(y - 1, 0), yd = std::min(y + 1, H - 1);
      const int lM = L(x, y), lN = L(x, yu), lS = L(x, yd), lW = L(xl, y), lE = L(xr, y);
      const int lNW = L(xl, yu), lNE = L(xr, yu), lSW = L(xl, yd), lSE = L(xr, yd);
      const int range = std::max({lM, lN, lS, lW, lE}) - std::min({lM, lN, lS, lW, lE});

      // Luma changing across rows: a horizontal edge (searched along x), else a vertical one.
      const int edgeHorz = std::abs(lNW + lSW - 2 * lW) + 2 * std::abs(lN + lS - 2 * lM) + std::abs(lNE + lSE - 2 * lE);
      const int edgeVert = std::abs(lNW + lNE - 2 * lN) + 2 * std::abs(lW + lE - 2 * lM) + std::abs(lSW + lSE - 2 * lS);
      const bool horz = edgeHorz >= edgeVert;
      const int l1 = horz ? lN : lW, l2 = horz ? lS : lE;
      const bool side1 = std::abs(l1 - lM) >= std::abs(l2 - lM);
      const int lAcross = side1 ? l1 : l2;
      const int px = horz ? 0 : (side1 ? -1 : 1), py = horz ? (side1 ? -1 : 1) : 0;  // to the pixel across
      const int xa = x + px, ya = y + py;
      if (xa < 0 || xa >= W || ya < 0 || ya >= H) continue;
      const int gradient = std::max(std::abs(l1 - lM), std::abs(l2 - lM));
      const int pairSum = lM + lAcross;  // twice the luma half way across
      const bool mBelow = 2 * lM < pairSum;

      // Search both ways along the edge, on the line half way to the pixel across, for where the
      // luma pair stops looking like this edge: its mean moves a quarter of the gradient away.
      // end(k) is twice that mean's departure; done when |end| >= gradient / 2.
      const int reachN = std::min(kSearchReach, horz ? x : y), reachP = std::min(kSearchReach, horz ? W - 1 - x : H - 1 - y);
      auto end = [&](int k) {
        const int x0 = x + (horz ? k : 0), y0 = y + (horz ? 0 : k);
        return L(x0, y0) + L(x0 + px, y0 + py) - pairSum;
      };
      int posN = std::min(1, reachN), posP = std::min(1, reachP);
      int endN = end(-posN), endP = end(posP);
      bool doneN = 2 * std::abs(endN) >= gradient || posN == reachN;
      bool doneP = 2 * std::abs(endP) >= gradient || posP == reachP;
      for (int step : kSearchSteps) {
        if (doneN && doneP) break;
        if (!doneN) {
          posN = std::min(posN + step, reachN);
          endN = end(-posN);
          doneN = 2 * std::abs(endN) >= gradient || posN == reachN;
        }
        if (!doneP) {
          posP = std::min(posP + step, reachP);
          endP = end(posP);
          doneP = 2 * std::abs(endP) >= gradient || posP == reachP;
        }
      }
      // The nearer end decides: this pixel is blended by how near it lies, when the luma there
      // moves the way that makes this pixel the edge's (FXAA's "good span").
      const bool towardsN = posN < posP;
      const bool goodSpan = towardsN ? ((endN < 0) != mBelow) : ((endP < 0) != mBelow);
      const float span = static_cast<float>(std::max(posN + posP, 1));
      const float offsetEdge = goodSpan ? 0.5f - static_cast<float>(std::min(posN, posP)) / span : 0.0f;
      // Sub-pixel: a pixel unlike all its neighbours (a thin line, a corner) is softened.
      const float average = static_cast<float>(2 * (lN + lS + lW + lE) + lNW + lNE + lSW + lSE) / 12.0f;
      const float c = std::min(std::abs(average - static_cast<float>(lM)) / static_cast<float>(std::max(range, 1)), 1.0f);
      const float f = (3 - 2 * c) * c * c;
      const float offset = std::max(offsetEdge, f * f * options.subpix);
      if (offset <= 0.0f) continue;

      const uint8_t* m = in + 4 * x;
      const uint8_t* a = row(ya) + 4 * xa;
      uint8_t rgb[3];
      for (int ch = 0; ch < 3; ++ch)
        rgb[ch] = static_cast<uint8_t>(static_cast<float>(m[ch]) + (static_cast<float>(a[ch]) - m[ch]) * offset + 0.5f);
      onBlend(y, x, rgb);
      ++stats.edgePixels;
    }
  }
  return stats;
}

}  // namespace

FxaaStats fxaa(const uint8_t* src, long srcStride, int width, int height, Image& dst,
               const std::vector<PixelRect>& keep, const FxaaOptions& options) {
  if (dst.width != width || dst.height != height) dst = Image(width, height);
  const size_t W = static_cast<size_t>(width);
  return filter(
      src, srcStride, width, height, keep, options,
      [&](int y, const uint8_t* in) { opaqueRow(in, &dst.rgba[static_cast<size_t>(y) * W * 4], width); },
      [&](int y, int x, const uint8_t* rgb) { std::memcpy(&dst.rgba[(static_cast<size_t>(y) * W + x) * 4], rgb, 3); });
}

FxaaStats finishInPlace(RawFrame& frame) {
  if (!frame.fxaa || frame.width <= 0 || frame.height <= 0) return {};
  const long stride = 4L * frame.width;
  uint8_t* top = frame.rgba.data() + stride * (frame.height - 1);
  // Every blend reads the frame as drawn, so the blended pixels wait until the filter is done.
  struct Pending {
    long offset;
    uint8_t rgb[3];
  };
  thread_local std::vector<Pending> pending;
  pending.clear();
  const FxaaStats stats = filter(
      top, -stride, frame.width, frame.height, frame.keep, FxaaOptions{}, [](int, const uint8_t*) {},
      [&](int y, int x, const uint8_t* rgb) { pending.push_back({-stride * y + 4L * x, {rgb[0], rgb[1], rgb[2]}}); });
  for (const Pending& p : pending) std::memcpy(top + p.offset, p.rgb, 3);
  return stats;
}

FxaaStats finishFrame(const RawFrame& frame, Image& out) {
  const long stride = 4L * frame.width;
  if (frame.width <= 0 || frame.height <= 0) {
    out = Image();
    return {};
  }
  // GL's rows run bottom-up: the image's row y is GL's row height - 1 - y.
  const uint8_t* top = frame.rgba.data() + stride * (frame.height - 1);
  if (frame.fxaa) return fxaa(top, -stride, frame.width, frame.height, out, frame.keep);
  copyOpaque(top, -stride, frame.width, frame.height, out);
  return {};
}

}  // namespace substep::render
