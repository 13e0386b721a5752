#include "render/image.h"

// Declarations only: libstb-dev compiles the implementations into libstb.
#include <stb_image.h>
#include <stb_image_write.h>
#include <turbojpeg.h>

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>

namespace substep::render {

Image::Image(int w, int h, uint32_t fill) : width(w), height(h), rgba(static_cast<size_t>(w) * h * 4) {
  const uint8_t c[4] = {static_cast<uint8_t>(fill >> 24), static_cast<uint8_t>(fill >> 16),
                        static_cast<uint8_t>(fill >> 8), static_cast<uint8_t>(fill)};
  for (size_t i = 0; i < rgba.size(); i += 4) std::memcpy(&rgba[i], c, 4);
}

void Image::blit(const Image& src, int x, int y) {
  const int x0 = std::max(0, x), x1 = std::min(width, x + src.width);
  if (x1 <= x0) return;
  for (int row = std::max(0, y); row < std::min(height, y + src.height); ++row)
    std::memcpy(pixel(x0, row), src.pixel(x0 - x, row - y), static_cast<size_t>(x1 - x0) * 4);
}

std::vector<uint8_t> encodePng(const Image& img) {
  std::vector<uint8_t> out;
  auto sink = [](void* ctx, void* data, int size) {
    auto* v = static_cast<std::vector<uint8_t>*>(ctx);
    v->insert(v->end(), static_cast<uint8_t*>(data), static_cast<uint8_t*>(data) + size);
  };
  if (!stbi_write_png_to_func(sink, &out, img.width, img.height, 4, img.rgba.data(), img.width * 4))
    throw std::runtime_error("PNG encoding failed (" + std::to_string(img.width) + "x" + std::to_string(img.height) + ")");
  return out;
}

namespace {

// One compressor a thread (the session encoders and clip threads each have theirs): a handle holds
// its buffers between frames, and is not to be shared between threads at once.
struct TurboCompressor {
  tjhandle h = tjInitCompress();
  ~TurboCompressor() {
    if (h) tjDestroy(h);
  }
};

}  // namespace

std::string encodeJpeg(const Image& img, int quality) {
  thread_local TurboCompressor c;
  const std::string size = std::to_string(img.width) + "x" + std::to_string(img.height);
  if (!c.h) throw std::runtime_error("JPEG encoding failed (" + size + "): libjpeg-turbo: " + tjGetErrorStr2(nullptr));
  unsigned char* buf = nullptr;
  unsigned long bytes = 0;
  if (tjCompress2(c.h, img.rgba.data(), img.width, img.width * 4, img.height, TJPF_RGBA, &buf, &bytes, TJSAMP_420,
                  std::clamp(quality, 1, 100), 0) != 0) {
    const std::string why = tjGetErrorStr2(c.h);
    tjFree(buf);
    throw std::runtime_error("JPEG encoding failed (" + size + "): " + why);
  }
  std::string out(reinterpret_cast<const char*>(buf), bytes);
  tjFree(buf);
  return out;
}

Image resized(const Image& img, int width, int height) {
  Image out(width, height);
  if (img.width <= 0 || img.height <= 0) return out;
  // The source coordinate of a destination pixel's centre, clamped to the edge pixels' centres.
  auto axis = [](int n, int from, int i, int& i0, int& i1, float& f) {
    const float x = std::clamp((static_cast<float>(i) + 0.5f) * static_cast<float>(from) / static_cast<float>(n) - 0.5f,
                               0.0f, static_cast<float>(from - 1));
    i0 = static_cast<int>(x);
    i1 = std::min(i0 + 1, from - 1);
    f = x - static_cast<float>(i0);
  };
  for (int y = 0; y < height; ++y) {
    int y0, y1;
    float fy;
    axis(height, img.height, y, y0, y1, fy);
    for (int x = 0; x < width; ++x) {
      int x0, x1;
      float fx;
      axis(width, img.width, x, x0, x1, fx);
      auto at = [&](int px, int py, int c) { return static_cast<float>(img.rgba[(static_cast<size_t>(py) * img.width + px) * 4 + c]); };
      for (int c = 0; c < 4; ++c) {
        const float top = at(x0, y0, c) + (at(x1, y0, c) - at(x0, y0, c)) * fx;
        const float bottom = at(x0, y1, c) + (at(x1, y1, c) - at(x0, y1, c)) * fx;
        out.rgba[(static_cast<size_t>(y) * width + x) * 4 + c] = static_cast<uint8_t>(top + (bottom - top) * fy + 0.5f);
      }
    }
  }
  return out;
}

Image decodePng(const std::vector<uint8_t>& bytes) {
  try {
    return decodeImage(bytes.data(), bytes.size());
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(std::string("not a readable PNG: ") + e.what());
  }
}

Image decodeImage(const void* bytes, size_t size) {
  int w = 0, h = 0, n = 0;
  stbi_uc* data = stbi_load_from_memory(static_cast<const stbi_uc*>(bytes), static_cast<int>(size), &w, &h, &n, 4);
  if (!data) throw std::runtime_error(stbi_failure_reason());
  Image img;
  img.width = w;
  img.height = h;
  img.rgba.assign(data, data + static_cast<size_t>(w) * h * 4);
  stbi_image_free(data);
  return img;
}

Image readPng(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot open: " + std::strerror(errno));
  const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), {});
  try {
    return decodePng(bytes);
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
}

void writePng(const std::string& path, const Image& img) {
  const std::vector<uint8_t> bytes = encodePng(img);
  const std::string temp = path + ".part" + std::to_string(getpid());
  {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error(path + ": cannot create " + temp + ": " + std::strerror(errno));
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) {
      std::remove(temp.c_str());
      throw std::runtime_error(path + ": write failed (disk full?)");
    }
  }
  std::error_code ec;
  std::filesystem::rename(temp, path, ec);
  if (ec) {
    std::remove(temp.c_str());
    throw std::runtime_error(path + ": cannot rename " + temp + " into place: " + ec.message());
  }
}

std::string CompareResult::summary() const {
  char buf[160];
  if (!sameSize) {
    std::snprintf(buf, sizeof buf, "sizes differ: expected %dx%d, actual %dx%d", expectedWidth, expectedHeight,
                  actualWidth, actualHeight);
    return buf;
  }
  std::snprintf(buf, sizeof buf, "%lld pixels differ (%.4f%%), largest channel difference %d", differing, share * 100,
                maxDelta);
  return buf;
}

CompareResult compareImages(const Image& expected, const Image& actual, const CompareOptions& o) {
  CompareResult r;
  r.expectedWidth = expected.width, r.expectedHeight = expected.height;
  r.actualWidth = actual.width, r.actualHeight = actual.height;
  r.sameSize = expected.width == actual.width && expected.height == actual.height && !expected.empty();
  if (!r.sameSize) return r;
  r.diff = Image(expected.width, expected.height);
  for (size_t i = 0; i < expected.rgba.size(); i += 4) {
    int d = 0;
    for (int c = 0; c < 4; ++c) d = std::max(d, std::abs(int(expected.rgba[i + c]) - int(actual.rgba[i + c])));
    r.maxDelta = std::max(r.maxDelta, d);
    uint8_t* out = &r.diff.rgba[i];
    if (d > o.threshold) {
      ++r.differing;
      out[0] = 255, out[1] = 0, out[2] = 0;
    } else {
      // The expected image at a third of its brightness, so red stands out and the scene is still recognisable.
      const int grey = (expected.rgba[i] + expected.rgba[i + 1] + expected.rgba[i + 2]) / 9;
      out[0] = out[1] = out[2] = static_cast<uint8_t>(grey);
    }
    out[3] = 255;
  }
  r.share = static_cast<double>(r.differing) / (static_cast<double>(expected.width) * expected.height);
  r.match = r.share <= o.maxShare;
  return r;
}

}  // namespace substep::render
