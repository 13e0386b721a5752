#include "render/frame_sink.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>

namespace substep::render {

namespace fs = std::filesystem;

namespace {

std::string partName(const std::string& path) { return path + ".part" + std::to_string(getpid()); }

std::string trimSlashes(std::string s) {
  while (s.size() > 1 && s.back() == '/') s.pop_back();
  return s;
}

}  // namespace

void PngSink::commit() {
  if (last_.empty()) throw std::runtime_error(path_ + ": no frame was drawn");
  writePng(path_, last_);  // itself under a temporary name, renamed
}

std::string PngFolderSink::stagingPath(const std::string& folder) { return partName(trimSlashes(folder)); }

std::string PngFolderSink::frameName(long long k) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "frame_%05lld.png", k);
  return buf;
}

PngFolderSink::PngFolderSink(const std::string& folder)
    : given_(folder), dir_(trimSlashes(folder)), stage_(stagingPath(folder)) {
  std::error_code ec;
  if (fs::exists(dir_, ec) && !fs::is_directory(dir_, ec)) throw OutputError(given_ + ": exists and is not a folder");
  fs::create_directory(stage_, ec);
  if (ec) throw OutputError(given_ + ": cannot create " + stage_ + ": " + ec.message());
}

PngFolderSink::~PngFolderSink() {
  std::error_code ec;
  if (!committed_) fs::remove_all(stage_, ec);
}

void PngFolderSink::write(const Image& frame) {
  writePng(stage_ + "/" + frameName(count_), frame);
  ++count_;
}

void PngFolderSink::commit() {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) throw std::runtime_error(dir_ + ": cannot create the folder: " + ec.message());
  // Frames of an earlier, longer render would make the sequence look longer than it is.
  for (const auto& e : fs::directory_iterator(dir_, ec)) {
    const std::string f = e.path().filename().string();
    if (f.size() >= 15 && f.compare(0, 6, "frame_") == 0 && f.compare(f.size() - 4, 4, ".png") == 0) {
      const std::string digits = f.substr(6, f.size() - 10);
      if (digits.size() <= 12 && std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; }) &&
          std::stoll(digits) >= count_)
        fs::remove(e.path(), ec);
    }
  }
  for (long long k = 0; k < count_; ++k) {
    fs::rename(stage_ + "/" + frameName(k), dir_ + "/" + frameName(k), ec);
    if (ec) throw std::runtime_error(dir_ + ": cannot move " + frameName(k) + " into place: " + ec.message());
  }
  fs::remove_all(stage_, ec);
  committed_ = true;
}

VideoSink::VideoSink(const std::string& ffmpeg, const std::string& path, int width, int height, const VideoOptions& o)
    : path_(path), temp_(partName(path)), encoder_(std::make_unique<VideoEncoder>(ffmpeg, temp_, width, height, o)) {}

VideoSink::~VideoSink() {
  encoder_.reset();  // an unfinished encoder stops ffmpeg and removes its file
  std::error_code ec;
  fs::remove(temp_, ec);  // finished, but not renamed
}

void VideoSink::commit() {
  encoder_->finish();
  std::error_code ec;
  fs::rename(temp_, path_, ec);
  if (ec) throw std::runtime_error(path_ + ": cannot rename " + temp_ + " into place: " + ec.message());
}

}  // namespace substep::render
