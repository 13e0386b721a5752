// RGBA images, PNG files (stb_image / stb_image_write) and the tolerant comparison the snapshot
// tests use.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace substep::render {

struct Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;  // row 0 at the top, 4 bytes a pixel

  Image() = default;
  Image(int w, int h, uint32_t fill = 0x000000ff);  // fill as 0xRRGGBBAA
  uint8_t* pixel(int x, int y) { return &rgba[(static_cast<size_t>(y) * width + x) * 4]; }
  const uint8_t* pixel(int x, int y) const { return &rgba[(static_cast<size_t>(y) * width + x) * 4]; }
  bool empty() const { return width == 0 || height == 0; }
  // Copies `src` with its top-left corner at (x, y), clipped.
  void blit(const Image& src, int x, int y);
};

std::vector<uint8_t> encodePng(const Image& img);
Image decodePng(const std::vector<uint8_t>& bytes);   // throws std::runtime_error
// Baseline JPEG (libjpeg-turbo, 4:2:0 chroma), alpha dropped: the server's streamed frames.
// Quality 1-100. Thread-safe (a compressor per thread).
std::string encodeJpeg(const Image& img, int quality);
// Any format stb_image reads (PNG, JPEG); throws std::runtime_error.
Image decodeImage(const void* data, size_t size);
// Bilinear, pixel centres aligned: a frame drawn smaller shown at a clip's size.
Image resized(const Image& img, int width, int height);
Image readPng(const std::string& path);               // throws std::runtime_error naming the file
// Writes under a temporary name in the same folder and renames it into place; throws
// std::runtime_error naming the file when it cannot.
void writePng(const std::string& path, const Image& img);

// Tolerant comparison: a pixel differs when any channel differs by more than `threshold`
// (0-255); the images match when the share of differing pixels is at most `maxShare`. The
// defaults are the snapshot tests' and `substep snapshot`'s (docs/snapshots.md): llvmpipe draws
// a frame identically every time on a machine, so they only absorb rounding between builds of
// it, and a 2 cm move of a box (under a pixel at 480x270) differs by several times the share.
struct CompareOptions {
  int threshold = 24;
  double maxShare = 0.0002;  // 26 pixels of 480x270
};

struct CompareResult {
  bool sameSize = false;     // sizes differ: a mismatch, with no diff image
  int expectedWidth = 0, expectedHeight = 0, actualWidth = 0, actualHeight = 0;
  long long differing = 0;   // pixels over the threshold
  double share = 0;          // differing / all pixels
  int maxDelta = 0;          // largest channel difference anywhere
  bool match = false;
  Image diff;                // the expected image, faded, with differing pixels in red (sizes equal only)
  std::string summary() const;
};

CompareResult compareImages(const Image& expected, const Image& actual, const CompareOptions& o = {});

}  // namespace substep::render
