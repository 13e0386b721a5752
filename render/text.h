// Text for the heads-up overlay: a TrueType font (DejaVu Sans from fonts-dejavu-core) packed into
// a one-channel atlas with stb_truetype, and strings laid out as textured quads in pixels.
#pragma once

#include <stb_truetype.h>

#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

namespace substep::render {

// $SUBSTEP_FONT if set, else DejaVu Sans.
std::string defaultFontPath();

// Code points of a UTF-8 string; malformed bytes become U+FFFD.
std::vector<uint32_t> decodeUtf8(const std::string& s);

struct GlyphQuad {
  float x0, y0, x1, y1;  // pixels, y down from the top of the frame
  float s0, t0, s1, t1;  // atlas coordinates
};

class Font {
 public:
  // Packs ASCII, Latin-1, Greek and a few symbols (≤ ≥ → × · …) at `pixelHeight`.
  // Throws std::runtime_error naming the file (and the package that provides it) when it cannot.
  Font(const std::string& path, float pixelHeight);
  ~Font();
  Font(const Font&) = delete;
  Font& operator=(const Font&) = delete;

  // Quads of `text` with its baseline at y, starting at x; characters the font lacks are skipped.
  std::vector<GlyphQuad> layout(const std::string& text, float x, float baseline) const;
  float width(const std::string& text) const;
  float ascent() const { return ascent_; }
  float lineHeight() const { return lineHeight_; }
  float pixelHeight() const { return pixelHeight_; }

  int atlasWidth() const { return atlasW_; }
  int atlasHeight() const { return atlasH_; }
  const std::vector<uint8_t>& atlas() const { return atlas_; }  // coverage, row 0 at the top

 private:
  std::vector<uint8_t> fontData_;
  std::vector<uint8_t> atlas_;
  int atlasW_ = 0, atlasH_ = 0;
  float pixelHeight_, ascent_ = 0, lineHeight_ = 0;
  std::vector<stbtt_packedchar> chars_;
  std::unordered_map<uint32_t, int> index_;  // code point to chars_
};

}  // namespace substep::render
