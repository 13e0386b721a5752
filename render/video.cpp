#include "render/video.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <vector>

extern char** environ;

namespace substep::render {

std::string findProgram(const std::string& name) {
  auto executable = [](const std::string& p) {
    struct stat st;
    return stat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode) && access(p.c_str(), X_OK) == 0;
  };
  if (name.find('/') != std::string::npos) return executable(name) ? name : "";
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const std::string p = (dir.empty() ? "." : dir) + "/" + name;
    if (executable(p)) return p;
  }
  return "";
}

std::string findFfmpeg() {
  if (const char* env = std::getenv("SUBSTEP_FFMPEG"); env && *env) return findProgram(env);
  return findProgram("ffmpeg");
}

void rgbaToYuv420(const uint8_t* top, long stride, int width, int height, std::vector<uint8_t>& out) {
  const size_t W = static_cast<size_t>(width), H = static_cast<size_t>(height);
  out.resize(W * H * 3 / 2);
  // swscale's coefficients (BT.601 scaled to 219 and 224 levels, in 1/32768) and its rounding:
  // Y is exactly ffmpeg's. U and V: each row's pair of pixels as swscale takes them (in 1/64
  // level), then the mean of the two rows, where swscale's vertical filter is a little longer.
  constexpr int32_t RY = 8414, GY = 16519, BY = 3208;
  constexpr int32_t RU = -4857, GU = -9535, BU = 14392, RV = 14392, GV = -12052, BV = -2340;
  uint8_t* Y = out.data();
  uint8_t* U = Y + W * H;
  uint8_t* V = U + W * H / 4;
  auto luma = [](const uint8_t* __restrict px, uint8_t* __restrict y, size_t n) {
    for (size_t i = 0; i < n; ++i) {
      const int32_t r = px[4 * i], g = px[4 * i + 1], b = px[4 * i + 2];
      y[i] = static_cast<uint8_t>((RY * r + GY * g + BY * b + (32 << 14) + (1 << 8) + (32 << 9)) >> 15);
    }
  };
  auto pairU = [](int32_t r, int32_t g, int32_t b) { return (RU * r + GU * g + BU * b + (256 << 15) + (1 << 9)) >> 10; };
  auto pairV = [](int32_t r, int32_t g, int32_t b) { return (RV * r + GV * g + BV * b + (256 << 15) + (1 << 9)) >> 10; };
  // A pair of rows at a time, Y and then U and V of it, while its pixels are in the cache.
  for (size_t y = 0; y < H / 2; ++y) {
    const uint8_t* a = top + stride * static_cast<long>(2 * y);
    const uint8_t* b = a + stride;
    luma(a, Y + W * (2 * y), W);
    luma(b, Y + W * (2 * y + 1), W);
    for (size_t x = 0; x < W / 2; ++x) {
      const uint8_t* p = a + 8 * x;
      const uint8_t* q = b + 8 * x;
      const int32_t r0 = p[0] + p[4], g0 = p[1] + p[5], b0 = p[2] + p[6];
      const int32_t r1 = q[0] + q[4], g1 = q[1] + q[5], b1 = q[2] + q[6];
      U[y * W / 2 + x] = static_cast<uint8_t>((pairU(r0, g0, b0) + pairU(r1, g1, b1) + 64) >> 7);
      V[y * W / 2 + x] = static_cast<uint8_t>((pairV(r0, g0, b0) + pairV(r1, g1, b1) + 64) >> 7);
    }
  }
}

void rgbaToYuv420(const Image& frame, std::vector<uint8_t>& out) {
  rgbaToYuv420(frame.rgba.data(), 4L * frame.width, frame.width, frame.height, out);
}

VideoEncoder::VideoEncoder(const std::string& ffmpeg, const std::string& path, int width, int height,
                           const VideoOptions& o)
    : path_(path), width_(width), height_(height) {
  if (width % 2 || height % 2)
    throw VideoError("H.264 in yuv420p needs an even width and height, got " + std::to_string(width) + "x" +
                     std::to_string(height));
  // ffmpeg's messages go to a log we show when it fails.
  char logName[] = "/tmp/substep-ffmpeg-XXXXXX";
  const int logFd = mkstemp(logName);
  if (logFd < 0) throw VideoError(std::string("cannot create a log file for ffmpeg: ") + std::strerror(errno));
  log_ = logName;
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0) {
    close(logFd);
    throw VideoError(std::string("cannot create a pipe to ffmpeg: ") + std::strerror(errno));
  }
  const std::vector<std::string> args = {
      ffmpeg, "-hide_banner", "-loglevel", "error", "-y",
      "-f", "rawvideo", "-pix_fmt", "yuv420p", "-s", std::to_string(width) + "x" + std::to_string(height),
      "-framerate", std::to_string(o.fps), "-i", "-",
      "-an", "-c:v", "libx264", "-preset", o.preset, "-crf", std::to_string(o.crf), "-pix_fmt", "yuv420p",
      "-movflags", "+faststart", "-f", "mp4", path};
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, fds[0], 0);
  posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_adddup2(&fa, logFd, 2);
  const int rc = posix_spawn(&pid_, ffmpeg.c_str(), &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  close(fds[0]);
  close(logFd);
  if (rc != 0) {
    close(fds[1]);
    std::remove(log_.c_str());
    pid_ = -1;
    throw VideoError("cannot start " + ffmpeg + ": " + std::strerror(rc));
  }
  fd_ = fds[1];
  // A frame in a few writes, not the ~20 that a pipe of 64 KiB takes, each waking ffmpeg (best
  // effort: the size is capped by /proc/sys/fs/pipe-max-size, 1 MiB by default).
  fcntl(fd_, F_SETPIPE_SZ, 1 << 20);
  // A dead ffmpeg must give us EPIPE, not kill us with SIGPIPE.
  struct sigaction ign {};
  ign.sa_handler = SIG_IGN;
  pipeIgnored_ = sigaction(SIGPIPE, &ign, &oldPipe_) == 0;
}

VideoEncoder::~VideoEncoder() {
  if (!finished_) {
    stop();
    std::remove(path_.c_str());
  }
  if (!log_.empty()) std::remove(log_.c_str());
  if (pipeIgnored_) sigaction(SIGPIPE, &oldPipe_, nullptr);
}

void VideoEncoder::stop() {
  if (fd_ >= 0) close(fd_);
  fd_ = -1;
  if (pid_ > 0) {
    kill(pid_, SIGTERM);
    int st;
    while (waitpid(pid_, &st, 0) < 0 && errno == EINTR) {
    }
    pid_ = -1;
  }
}

std::string VideoEncoder::logTail() const {
  std::ifstream in(log_);
  std::string line, all;
  std::vector<std::string> lines;
  while (std::getline(in, line))
    if (!line.empty()) lines.push_back(line);
  for (size_t i = lines.size() > 6 ? lines.size() - 6 : 0; i < lines.size(); ++i) all += "\n  ffmpeg: " + lines[i];
  return all;
}

void VideoEncoder::fail(const std::string& what) {
  // Collect ffmpeg's exit status and message before cleaning up.
  if (fd_ >= 0) close(fd_);
  fd_ = -1;
  std::string status;
  if (pid_ > 0) {
    int st = 0;
    while (waitpid(pid_, &st, 0) < 0 && errno == EINTR) {
    }
    pid_ = -1;
    if (WIFEXITED(st))
      status = " (ffmpeg exited with status " + std::to_string(WEXITSTATUS(st)) + ")";
    else if (WIFSIGNALED(st))
      status = " (ffmpeg was killed by signal " + std::to_string(WTERMSIG(st)) + ")";
  }
  throw VideoError(what + status + logTail());
}

void VideoEncoder::write(const Image& frame) { write(frame.rgba.data(), 4L * frame.width, frame.width, frame.height); }

void VideoEncoder::write(const uint8_t* top, long stride, int width, int height) {
  if (width != width_ || height != height_)
    throw VideoError("frame of " + std::to_string(width) + "x" + std::to_string(height) + " sent to a " +
                     std::to_string(width_) + "x" + std::to_string(height_) + " video");
  if (fd_ < 0) throw VideoError("the video is already closed");
  rgbaToYuv420(top, stride, width, height, yuv_);
  const uint8_t* p = yuv_.data();
  size_t left = yuv_.size();
  while (left > 0) {
    const ssize_t n = ::write(fd_, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("ffmpeg stopped taking frames for " + path_ + ": " + std::strerror(errno));
    }
    p += n;
    left -= static_cast<size_t>(n);
  }
}

void VideoEncoder::finish() {
  if (pid_ <= 0) throw VideoError("the video " + path_ + " was not completed");
  if (fd_ >= 0) close(fd_);
  fd_ = -1;
  int st = 0;
  while (waitpid(pid_, &st, 0) < 0 && errno == EINTR) {
  }
  pid_ = -1;
  if (!WIFEXITED(st) || WEXITSTATUS(st) != 0) {
    const std::string status = WIFEXITED(st) ? "exited with status " + std::to_string(WEXITSTATUS(st))
                                             : "was killed by signal " + std::to_string(WTERMSIG(st));
    throw VideoError("ffmpeg " + status + " while writing " + path_ + logTail());
  }
  finished_ = true;
}

}  // namespace substep::render
