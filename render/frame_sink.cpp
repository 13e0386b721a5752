#include "render/frame_sink.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
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

void VideoSink::writeRaw(const RawFrame& frame) {
  const long stride = 4L * frame.width;
  encoder_->write(frame.rgba.data() + stride * (frame.height - 1), -stride, frame.width, frame.height);
}

void VideoSink::commit() {
  encoder_->finish();
  std::error_code ec;
  fs::rename(temp_, path_, ec);
  if (ec) throw std::runtime_error(path_ + ": cannot rename " + temp_ + " into place: " + ec.message());
}

namespace {
double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

ThreadedSink::ThreadedSink(std::unique_ptr<FrameSink> inner, int depth)
    : inner_(std::move(inner)), depth_(static_cast<size_t>(std::max(depth, 1))), thread_([this] { run(); }) {}

ThreadedSink::~ThreadedSink() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
    queue_.clear();
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();  // after the frame being written
}

void ThreadedSink::run() {
  std::unique_lock<std::mutex> lock(mu_);
  for (;;) {
    cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (stop_) return;
    Job job = std::move(queue_.front());
    queue_.pop_front();
    busy_ = true;
    lock.unlock();
    std::exception_ptr error;
    double finishing = 0, writing = 0;
    try {
      auto t0 = std::chrono::steady_clock::now();
      const bool raw = job.isRaw && inner_->takesRaw();
      if (job.isRaw) {
        if (raw)
          finishInPlace(job.raw);
        else
          finishFrame(job.raw, finished_);
        finishing = secondsSince(t0);
        t0 = std::chrono::steady_clock::now();
      }
      if (raw)
        inner_->writeRaw(job.raw);
      else
        inner_->write(job.isRaw ? finished_ : job.image);
      writing = secondsSince(t0);
    } catch (...) {
      error = std::current_exception();
    }
    lock.lock();
    finishing_ += finishing;
    writing_ += writing;
    busy_ = false;
    if (job.isRaw)
      spareRaw_.push_back(std::move(job.raw));
    else
      spare_.push_back(std::move(job.image));
    if (error) {
      error_ = error;
      queue_.clear();  // frames after a failed one are not written
      cv_.notify_all();
      return;
    }
    cv_.notify_all();
  }
}

void ThreadedSink::rethrowLocked() {
  if (error_) std::rethrow_exception(error_);
}

ThreadedSink::Job ThreadedSink::push(Job job) {
  const auto t0 = std::chrono::steady_clock::now();
  std::unique_lock<std::mutex> lock(mu_);
  cv_.wait(lock, [this] { return error_ || queue_.size() < depth_; });
  waited_ += secondsSince(t0);
  rethrowLocked();
  Job spare;
  spare.isRaw = job.isRaw;
  if (job.isRaw && !spareRaw_.empty()) {
    spare.raw = std::move(spareRaw_.back());
    spareRaw_.pop_back();
  } else if (!job.isRaw && !spare_.empty()) {
    spare.image = std::move(spare_.back());
    spare_.pop_back();
  }
  queue_.push_back(std::move(job));
  lock.unlock();
  cv_.notify_all();
  return spare;
}

void ThreadedSink::pass(Image& frame) {
  Job job;
  job.image = std::move(frame);
  frame = push(std::move(job)).image;
}

void ThreadedSink::pass(RawFrame& frame) {
  Job job;
  job.raw = std::move(frame);
  job.isRaw = true;
  frame = push(std::move(job)).raw;
}

void ThreadedSink::write(const Image& frame) {
  Image copy = frame;
  pass(copy);
}

double ThreadedSink::finishSeconds() const {
  std::lock_guard<std::mutex> lock(mu_);
  return finishing_;
}

double ThreadedSink::writeSeconds() const {
  std::lock_guard<std::mutex> lock(mu_);
  return writing_;
}

double ThreadedSink::waitedSeconds() const {
  std::lock_guard<std::mutex> lock(mu_);
  return waited_;
}

void ThreadedSink::commit() {
  {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait(lock, [this] { return error_ || (queue_.empty() && !busy_); });
    rethrowLocked();
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
  const auto t0 = std::chrono::steady_clock::now();
  inner_->commit();
  writing_ += secondsSince(t0);
}

}  // namespace substep::render
