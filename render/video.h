// H.264 video by piping raw RGBA frames to the ffmpeg program (libx264, yuv420p).
#pragma once

#include "render/image.h"

#include <signal.h>
#include <sys/types.h>

#include <stdexcept>
#include <string>

namespace substep::render {

class VideoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The ffmpeg to run: $SUBSTEP_FFMPEG if set, else `ffmpeg` found on PATH; "" when there is none.
std::string findFfmpeg();
// An executable called `name` on PATH (or `name` itself when it contains a slash); "" if none.
std::string findProgram(const std::string& name);

struct VideoOptions {
  int fps = 60;
  int crf = 18;                      // x264 quality: 0 lossless .. 51 worst
  std::string preset = "veryfast";   // x264 speed/size trade-off
};

// Writes `path` (an MP4, whatever its name ends with). Until finish() succeeds the file is
// incomplete; destroying an unfinished encoder stops ffmpeg and removes the file.
class VideoEncoder {
 public:
  // Starts ffmpeg. Width and height must be even (yuv420p). Throws VideoError.
  VideoEncoder(const std::string& ffmpeg, const std::string& path, int width, int height, const VideoOptions& o);
  ~VideoEncoder();
  VideoEncoder(const VideoEncoder&) = delete;
  VideoEncoder& operator=(const VideoEncoder&) = delete;

  // Sends one frame (the encoder's size). Throws VideoError, with ffmpeg's message, when ffmpeg
  // has stopped.
  void write(const Image& frame);
  // Waits for ffmpeg to finish the file. Throws VideoError when it fails.
  void finish();

 private:
  [[noreturn]] void fail(const std::string& what);
  std::string logTail() const;
  void stop();

  std::string path_, log_;
  int width_, height_;
  int fd_ = -1;
  pid_t pid_ = -1;
  bool finished_ = false;
  struct sigaction oldPipe_ {};
  bool pipeIgnored_ = false;
};

}  // namespace substep::render
