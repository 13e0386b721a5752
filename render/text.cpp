#include "render/text.h"

// libstb-dev compiles the implementations into libstb; only the declarations are included here.
#include <stb_truetype.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <stdexcept>

namespace substep::render {

std::string defaultFontPath() {
  if (const char* env = std::getenv("SUBSTEP_FONT"); env && *env) return env;
  return "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
}

std::vector<uint32_t> decodeUtf8(const std::string& s) {
  std::vector<uint32_t> out;
  for (size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    int extra;
    uint32_t cp;
    if (c < 0x80) {
      extra = 0, cp = c;
    } else if ((c & 0xE0) == 0xC0) {
      extra = 1, cp = c & 0x1F;
    } else if ((c & 0xF0) == 0xE0) {
      extra = 2, cp = c & 0x0F;
    } else if ((c & 0xF8) == 0xF0) {
      extra = 3, cp = c & 0x07;
    } else {
      out.push_back(0xFFFD);
      ++i;
      continue;
    }
    bool ok = true;
    for (int k = 1; ok && k <= extra; ++k) {
      if (i + k >= s.size() || (static_cast<unsigned char>(s[i + k]) & 0xC0) != 0x80) ok = false;
      else cp = (cp << 6) | (static_cast<unsigned char>(s[i + k]) & 0x3F);
    }
    if (!ok) {
      out.push_back(0xFFFD);
      ++i;
      continue;
    }
    out.push_back(cp);
    i += static_cast<size_t>(extra) + 1;
  }
  return out;
}

Font::Font(const std::string& path, float pixelHeight) : pixelHeight_(pixelHeight) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw std::runtime_error("cannot open the overlay font " + path +
                             " (Debian package fonts-dejavu-core; or set SUBSTEP_FONT to a .ttf file)");
  fontData_.assign(std::istreambuf_iterator<char>(in), {});
  stbtt_fontinfo info;
  if (fontData_.empty() || !stbtt_InitFont(&info, fontData_.data(), stbtt_GetFontOffsetForIndex(fontData_.data(), 0)))
    throw std::runtime_error("the overlay font " + path + " is not a TrueType font");
  const float scale = stbtt_ScaleForPixelHeight(&info, pixelHeight);
  int asc, desc, gap;
  stbtt_GetFontVMetrics(&info, &asc, &desc, &gap);
  ascent_ = std::ceil(asc * scale);
  lineHeight_ = std::ceil((asc - desc + gap) * scale);

  // ASCII and Latin-1, Greek (κ, τ, ω, λ ...), punctuation (…, –), arrows, ≈, ≠, ≤, ≥: those the
  // font has (packing a missing one would fail the whole atlas).
  const std::pair<uint32_t, uint32_t> spans[] = {{0x20, 0x7E}, {0xA0, 0xFF}, {0x391, 0x3C9}, {0x2010, 0x2026},
                                                 {0x2190, 0x2193}, {0x2212, 0x2212}, {0x2248, 0x2248}, {0x2260, 0x2265}};
  std::vector<int> codepoints;
  for (const auto& [a, b] : spans)
    for (uint32_t c = a; c <= b; ++c)
      if (stbtt_FindGlyphIndex(&info, static_cast<int>(c)) != 0) codepoints.push_back(static_cast<int>(c));
  chars_.resize(codepoints.size());
  // Grow the atlas until every glyph fits.
  for (int side = 256; side <= 4096; side *= 2) {
    atlasW_ = atlasH_ = side;
    atlas_.assign(static_cast<size_t>(side) * side, 0);
    stbtt_pack_context pc;
    if (!stbtt_PackBegin(&pc, atlas_.data(), side, side, 0, 1, nullptr)) throw std::runtime_error("stbtt_PackBegin failed");
    stbtt_pack_range range{};
    range.font_size = pixelHeight;
    range.array_of_unicode_codepoints = codepoints.data();
    range.num_chars = static_cast<int>(codepoints.size());
    range.chardata_for_range = chars_.data();
    const int ok = stbtt_PackFontRanges(&pc, fontData_.data(), 0, &range, 1);
    stbtt_PackEnd(&pc);
    if (ok) {
      for (size_t i = 0; i < codepoints.size(); ++i) index_[static_cast<uint32_t>(codepoints[i])] = static_cast<int>(i);
      return;
    }
  }
  throw std::runtime_error("the overlay font does not fit a 4096² atlas at " + std::to_string(pixelHeight) + " px");
}

Font::~Font() = default;

std::vector<GlyphQuad> Font::layout(const std::string& text, float x, float baseline) const {
  std::vector<GlyphQuad> quads;
  float px = std::round(x), py = std::round(baseline);
  const stbtt_packedchar* chars = chars_.data();
  for (uint32_t cp : decodeUtf8(text)) {
    const auto it = index_.find(cp);
    if (it == index_.end()) continue;
    stbtt_aligned_quad q;
    stbtt_GetPackedQuad(chars, atlasW_, atlasH_, it->second, &px, &py, &q, 1);
    if (q.x1 > q.x0 && q.y1 > q.y0) quads.push_back({q.x0, q.y0, q.x1, q.y1, q.s0, q.t0, q.s1, q.t1});
  }
  return quads;
}

float Font::width(const std::string& text) const {
  float w = 0;
  for (uint32_t cp : decodeUtf8(text)) {
    const auto it = index_.find(cp);
    if (it != index_.end()) w += chars_[static_cast<size_t>(it->second)].xadvance;
  }
  return w;
}

}  // namespace substep::render
