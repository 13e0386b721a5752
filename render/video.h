// H.264 video by piping raw frames to the ffmpeg program (libx264, yuv420p), converted to
// yuv420p here: ffmpeg's own conversion from RGBA ran on its input thread and cost about a third
// of its time, and the pipe carries 1.5 bytes a pixel instead of 4.
#pragma once

#include "render/image.h"

#include <signal.h>
#include <sys/types.h>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace substep::render {

class VideoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The ffmpeg to run: $SUBSTEP_FFMPEG if set, else `ffmpeg` found on PATH; "" when there is none.
std::string findFfmpeg();
// An executable called `name` on PATH (or `name` itself when it contains a slash); "" if none.
std::string findProgram(const std::string& name);

// The frame in yuv420p as ffmpeg's default conversion makes it (BT.601, limited range: Y 16-235,
// U and V 16-240): Y of every pixel exactly as ffmpeg's, U and V of every 2x2 block, within one
// level of ffmpeg's but for about 1 % of them at sharp colour edges, where its vertical chroma
// filter reaches further. Width and height even.
void rgbaToYuv420(const Image& frame, std::vector<uint8_t>& out);
// The same from RGBA rows (alpha ignored) whose row y, counted from the top, starts at
// top + y * stride bytes: a negative stride reads GL's bottom-up rows.
void rgbaToYuv420(const uint8_t* top, long stride, int width, int height, std::vector<uint8_t>& out);

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
  // A frame's RGBA rows through a stride (rgbaToYuv420); alpha ignored.
  void write(const uint8_t* top, long stride, int width, int height);
  // Waits for ffmpeg to finish the file. Throws VideoError when it fails.
  void finish();

 private:
  [[noreturn]] void fail(const std::string& what);
  std::string logTail() const;
  void stop();

  std::string path_, log_;
  int width_, height_;
  std::vector<uint8_t> yuv_;  // the frame being sent, reused
  int fd_ = -1;
  pid_t pid_ = -1;
  bool finished_ = false;
  struct sigaction oldPipe_ {};
  bool pipeIgnored_ = false;
};

}  // namespace substep::render
