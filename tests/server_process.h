// For the tests of `substep serve` (test_server, test_server_load): the built binary started on a
// free loopback port, its address read from what it prints, stopped with SIGINT; raw requests
// for what httplib's client would tidy up (paths with "..").
#pragma once

#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <memory>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace substep_test {

using json = nlohmann::json;

class ServerProcess {
 public:
  // Starts `substep serve --port 0 ARGS` from the source folder; waits for its address.
  explicit ServerProcess(const std::vector<std::string>& args) {
    int out[2];
    if (pipe(out) != 0) throw std::runtime_error("pipe");
    pid_ = fork();
    if (pid_ == 0) {
      dup2(out[1], 1);
      dup2(out[1], 2);
      close(out[0]);
      close(out[1]);
      if (chdir(SUBSTEP_SOURCE_DIR) != 0) _exit(127);
      std::vector<std::string> all = {SUBSTEP_EXE, "serve", "--port", "0"};
      all.insert(all.end(), args.begin(), args.end());
      std::vector<char*> argv;
      for (auto& a : all) argv.push_back(a.data());
      argv.push_back(nullptr);
      execv(argv[0], argv.data());
      _exit(127);
    }
    close(out[1]);
    fd_ = out[0];
    reader_ = std::thread([this] {
      char buf[4096];
      ssize_t n;
      while ((n = read(fd_, buf, sizeof buf)) > 0) {
        std::lock_guard<std::mutex> lk(m_);
        output_.append(buf, static_cast<size_t>(n));
      }
    });
    const std::regex address(R"(http://127\.0\.0\.1:([0-9]+)/)");
    for (int i = 0; i < 600 && port_ == 0; ++i) {  // up to 60 s (sanitizer builds start slowly)
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      std::smatch m;
      const std::string o = output();
      if (std::regex_search(o, m, address)) port_ = std::stoi(m[1]);
      if (waitpid(pid_, &status_, WNOHANG) == pid_) {
        exited_ = true;
        break;
      }
    }
    if (port_ == 0) throw std::runtime_error("substep serve did not start: " + output());
  }

  ~ServerProcess() {
    if (!exited_) {
      kill(pid_, SIGINT);
      waitpid(pid_, &status_, 0);
    }
    if (reader_.joinable()) reader_.join();
    close(fd_);
  }

  // SIGINT, then its exit status (-1 if it had to be killed after `timeout` seconds).
  int interrupt(double timeout = 20) {
    kill(pid_, SIGINT);
    for (int i = 0; i < timeout * 20; ++i) {
      if (waitpid(pid_, &status_, WNOHANG) == pid_) {
        exited_ = true;
        return WIFEXITED(status_) ? WEXITSTATUS(status_) : -1;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    kill(pid_, SIGKILL);
    waitpid(pid_, &status_, 0);
    exited_ = true;
    return -1;
  }

  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  std::string output() const {
    std::lock_guard<std::mutex> lk(m_);
    return output_;
  }
  std::unique_ptr<httplib::Client> client(double timeout = 30) const {
    auto c = std::make_unique<httplib::Client>("127.0.0.1", port_);
    c->set_read_timeout(static_cast<time_t>(timeout), 0);
    c->set_connection_timeout(5, 0);
    return c;
  }
  // Resident memory of the server [KiB], from /proc.
  long rssKiB() const {
    std::ifstream in("/proc/" + std::to_string(pid_) + "/status");
    std::string line;
    while (std::getline(in, line))
      if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
    return -1;
  }

 private:
  pid_t pid_ = -1;
  int fd_ = -1, port_ = 0, status_ = 0;
  bool exited_ = false;
  std::thread reader_;
  mutable std::mutex m_;
  std::string output_;
};

// The answer to a request written byte for byte (no client normalises its path): status line,
// headers and body.
inline std::string rawRequest(int port, const std::string& request) {
  const int s = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(s, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    close(s);
    return "";
  }
  timeval tv{10, 0};
  setsockopt(s, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  (void)!write(s, request.data(), request.size());
  std::string r;
  char buf[4096];
  ssize_t n;
  while ((n = read(s, buf, sizeof buf)) > 0) r.append(buf, static_cast<size_t>(n));
  close(s);
  return r;
}

inline int rawStatus(const std::string& response) {
  if (response.size() < 12 || response.compare(0, 5, "HTTP/") != 0) return -1;
  return std::stoi(response.substr(9, 3));
}

// Reads a stream (MJPEG or events) for up to `seconds`, or until `enough` says so.
inline std::string readStream(httplib::Client& c, const std::string& path, double seconds,
                              const std::function<bool(const std::string&)>& enough, int* status = nullptr) {
  std::string got;
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  auto res = c.Get(path.c_str(), [&](const char* data, size_t n) {
    got.append(data, n);
    return std::chrono::steady_clock::now() < end && !enough(got);
  });
  if (status) *status = res ? res->status : -1;
  return got;
}

// Count of non-overlapping occurrences.
inline int count(const std::string& s, const std::string& what) {
  int n = 0;
  for (size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + what.size())) ++n;
  return n;
}

}  // namespace substep_test
