// Where frames go: one PNG, a numbered PNG sequence, an H.264 video; the interface leaves room
// for a stream (a JPEG per write(), closed at commit()).
//
// Frames come in order. commit() completes the output, which appears all at once: it is written
// under a temporary name (PATH.part<pid>, a staging folder for sequences) and renamed into
// place; a sink destroyed without commit() leaves nothing behind (a failure, a divergence,
// Ctrl-C). Errors: OutputError for a path that cannot be used, std::runtime_error (VideoError
// from ffmpeg) for a failure while writing.
#pragma once

#include "render/fxaa.h"
#include "render/image.h"
#include "render/video.h"

#include <condition_variable>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace substep::render {

class OutputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class FrameSink {
 public:
  virtual ~FrameSink() = default;
  virtual void write(const Image& frame) = 0;
  virtual void commit() = 0;
  // A sink that reads a raw frame as it is (after finishInPlace), with no image made of it.
  virtual bool takesRaw() const { return false; }
  virtual void writeRaw(const RawFrame&) { throw std::logic_error("this sink takes images, not raw frames"); }
};

// One PNG: the last frame written, encoded at commit().
class PngSink final : public FrameSink {
 public:
  explicit PngSink(std::string path) : path_(std::move(path)) {}
  void write(const Image& frame) override { last_ = frame; }
  void commit() override;

 private:
  std::string path_;
  Image last_;
};

// frame_00000.png, frame_00001.png, ... into a folder. Frames go to a sibling staging folder;
// commit() moves them into place and removes the frames of an earlier, longer sequence (other
// files in the folder stay).
class PngFolderSink final : public FrameSink {
 public:
  explicit PngFolderSink(const std::string& folder);  // throws OutputError
  ~PngFolderSink() override;
  PngFolderSink(const PngFolderSink&) = delete;
  PngFolderSink& operator=(const PngFolderSink&) = delete;
  void write(const Image& frame) override;
  void commit() override;

  static std::string stagingPath(const std::string& folder);  // FOLDER.part<pid>
  static std::string frameName(long long k);                  // frame_00042.png

 private:
  std::string given_, dir_, stage_;
  long long count_ = 0;
  bool committed_ = false;
};

// H.264 (libx264, yuv420p) through the ffmpeg program, into PATH.part<pid>, renamed at commit().
class VideoSink final : public FrameSink {
 public:
  // Starts ffmpeg; width and height even. Throws VideoError.
  VideoSink(const std::string& ffmpeg, const std::string& path, int width, int height, const VideoOptions& o);
  ~VideoSink() override;
  void write(const Image& frame) override { encoder_->write(frame); }
  void commit() override;
  // Converted from GL's bottom-up rows to the video's, with no flipped copy made.
  bool takesRaw() const override { return true; }
  void writeRaw(const RawFrame& frame) override;

 private:
  std::string path_, temp_;
  std::unique_ptr<VideoEncoder> encoder_;
};

// Another sink's writes on a thread of their own, so the next frame is drawn while this one is
// piped to ffmpeg or encoded as PNG. At most `depth` frames wait; pass() hands a frame over
// without copying it, finished or raw (then the anti-aliasing filter, and the row flip for a
// sink that does not take raw frames, run on the sink's thread too, beside the drawing of the
// next frame). An error of the inner sink comes out
// of the next pass(), write() or commit(). Destroyed without commit(), it drops the frames still
// waiting and destroys the inner sink, which leaves nothing behind.
class ThreadedSink final : public FrameSink {
 public:
  explicit ThreadedSink(std::unique_ptr<FrameSink> inner, int depth = 2);
  ~ThreadedSink() override;
  ThreadedSink(const ThreadedSink&) = delete;
  ThreadedSink& operator=(const ThreadedSink&) = delete;
  void write(const Image& frame) override;  // a copy
  // Takes the frame's pixels and gives back the buffer of a frame already written (same size
  // after the first few), so a renderer drawing into it causes no page faults.
  void pass(Image& frame);
  void pass(RawFrame& frame);  // finishFrame() on the sink's thread
  void commit() override;      // waits for every frame, then commits the inner sink

  double finishSeconds() const;  // finishFrame() of raw frames (FXAA and the row flip)
  double writeSeconds() const;   // the inner sink's time (ffmpeg taking frames, PNG encoding)
  double waitedSeconds() const;  // time pass() waited for room (the writing behind)

 private:
  struct Job {
    Image image;
    RawFrame raw;
    bool isRaw = false;
  };
  void run();
  Job push(Job job);  // waits for room, queues it, returns a spare buffer of its kind (or an empty one)
  void rethrowLocked();

  std::unique_ptr<FrameSink> inner_;
  const size_t depth_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<Job> queue_;          // frames to write, in order
  std::vector<Image> spare_;       // buffers of frames written
  std::vector<RawFrame> spareRaw_;
  Image finished_;                 // the sink thread's image of a raw frame
  bool busy_ = false, stop_ = false;
  std::exception_ptr error_;
  double finishing_ = 0, writing_ = 0, waited_ = 0;
  std::thread thread_;  // last: started once everything above exists
};

}  // namespace substep::render
