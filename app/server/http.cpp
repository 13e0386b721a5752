// The HTTP plumbing of `substep serve`: see http.h.
#include "app/server/http.h"

#include <atomic>

#include "physics/utf8.h"

#include "app/common.h"

#include <sys/stat.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

namespace substep::app::web {

namespace fs = std::filesystem;

namespace {

}  // namespace

std::string quote(const json& v) {
  const std::string s = v.dump();
  return s.size() > limits::kMaxMessageValue ? utf8Prefix(s, limits::kMaxMessageValue) + "..." : s;
}

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

// --- request fields ---

namespace {
std::atomic<size_t> jsonBodyLimit{64 * 1024};
}

void setJsonBodyLimit(size_t bytes) { jsonBodyLimit = bytes; }

Fields::Fields(const Request& req, const std::vector<std::string>& allowed) {
  if (req.body.size() > jsonBodyLimit)
    throw HttpError(413, "the request body is larger than " + std::to_string(jsonBodyLimit.load()) + " bytes");
  if (req.body.find_first_not_of(" \t\r\n") == std::string::npos) {
    j_ = json::object();
  } else {
    try {
      j_ = json::parse(req.body);
    } catch (const json::exception& e) {
      throw HttpError(400, std::string("body: expected a JSON object: ") + e.what());
    }
    if (!j_.is_object()) throw HttpError(400, "body: expected a JSON object, got " + quote(j_));
  }
  for (const auto& [k, v] : j_.items())
    if (std::find(allowed.begin(), allowed.end(), k) == allowed.end())
      throw HttpError(400, "unknown field \"" + utf8Prefix(k, limits::kMaxMessageValue) + "\"; expected " +
                               (allowed.empty() ? std::string("none") : "one of " + joined(allowed)));
}

bool Fields::flag(const std::string& k) const {
  const json& v = j_.at(k);
  if (!v.is_boolean()) throw HttpError(400, k + ": expected true or false, got " + quote(v));
  return v.get<bool>();
}

std::string Fields::text(const std::string& k, size_t maxLength) const {
  const json& v = j_.at(k);
  if (!v.is_string()) throw HttpError(400, k + ": expected a string, got " + quote(v));
  std::string s = v.get<std::string>();
  if (s.size() > maxLength)
    throw HttpError(400, k + ": expected at most " + std::to_string(maxLength) + " characters, got " +
                             std::to_string(s.size()));
  return s;
}

Vec3 Fields::vec3(const std::string& k, const Range& r) const {
  const json& v = j_.at(k);
  if (!v.is_array() || v.size() != 3) throw HttpError(400, k + ": expected [x, y, z], got " + quote(v));
  Vec3 x;
  for (int i = 0; i < 3; ++i) x[i] = numberOf(v[static_cast<size_t>(i)], k + "[" + std::to_string(i) + "]", r, false);
  return x;
}

std::pair<double, double> Fields::pair(const std::string& k, const Range& r) const {
  const json& v = j_.at(k);
  if (!v.is_array() || v.size() != 2) throw HttpError(400, k + ": expected [a, b], got " + quote(v));
  return {numberOf(v[0], k + "[0]", r, false), numberOf(v[1], k + "[1]", r, false)};
}

double Fields::numberOf(const json& v, const std::string& name, const Range& r, bool integer) {
  const std::string expected = r.expected(integer);
  if (!v.is_number()) throw HttpError(400, name + ": expected " + expected + ", got " + quote(v));
  const double x = v.get<double>();
  if (!std::isfinite(x) || !r.contains(x) || (integer && x != std::floor(x)))
    throw HttpError(400, name + ": expected " + expected + ", got " + quote(v));
  return x;
}

// --- answers ---

void sendJson(Response& res, const json& j, int status) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(j.dump(), "application/json");
}

void sendError(Response& res, int status, const std::string& message) {
  sendJson(res, {{"error", validUtf8(message)}}, status);
}

// --- files ---

const char* contentType(const std::string& ext) {
  static const std::map<std::string, const char*> types = {
      {".html", "text/html; charset=utf-8"}, {".js", "text/javascript; charset=utf-8"},
      {".mjs", "text/javascript; charset=utf-8"}, {".css", "text/css; charset=utf-8"},
      {".json", "application/json"}, {".svg", "image/svg+xml"}, {".png", "image/png"},
      {".jpg", "image/jpeg"}, {".ico", "image/x-icon"}, {".txt", "text/plain; charset=utf-8"},
      {".csv", "text/csv; charset=utf-8"}, {".mp4", "video/mp4"}, {".woff2", "font/woff2"},
      {".md", "text/markdown; charset=utf-8"}};
  const auto it = types.find(ext);
  return it == types.end() ? nullptr : it->second;
}

std::string staticFile(const std::string& root, const std::string& rel) {
  if (root.empty() || rel.empty() || rel.size() > 512 || rel.front() == '/' ||
      rel.find_first_of(std::string("\\\0:", 3)) != std::string::npos)
    return "";
  std::string path = root;
  std::stringstream ss(rel);
  std::string seg;
  while (std::getline(ss, seg, '/')) {
    if (seg.empty() || seg[0] == '.') return "";  // "..", ".", hidden files, "//"
    path += "/" + seg;
    struct stat st {};
    if (lstat(path.c_str(), &st) != 0 || S_ISLNK(st.st_mode)) return "";
  }
  if (rel.back() == '/') return "";
  struct stat st {};
  if (lstat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return "";
  std::error_code ec;
  const std::string canon = fs::canonical(path, ec).string(), rootCanon = fs::canonical(root, ec).string();
  if (ec || canon.compare(0, rootCanon.size() + 1, rootCanon + "/") != 0) return "";
  return canon;
}

void serveFile(const std::string& root, const std::string& rel, Response& res) {
  const std::string path = staticFile(root, rel);
  const char* type = contentType(fs::path(rel).extension().string());
  if (path.empty() || !type) throw HttpError(404, "no such file");
  std::ifstream in(path, std::ios::binary);
  std::string body((std::istreambuf_iterator<char>(in)), {});
  if (!in && !in.eof()) throw HttpError(500, "cannot read the file");
  res.set_header("Cache-Control", "no-cache");
  res.set_header("X-Content-Type-Options", "nosniff");
  res.set_content(std::move(body), type);
}

// --- routes ---

Router::Router(httplib::Server& http, size_t maxBody) : http_(http) {
  http_.set_error_handler([this, maxBody](const Request& req, Response& res) {
    if (!res.body.empty()) return;
    if (res.status == 404) {
      notFound(req, res);
      return;
    }
    if (res.status == 413)
      sendError(res, 413, "the request body is larger than " + std::to_string(maxBody) + " bytes");
    else if (res.status == 400)
      sendError(res, 400, "malformed request");
    else
      sendError(res, res.status, "the request could not be answered (HTTP " + std::to_string(res.status) + ")");
  });
}

void Router::add(const std::string& method, const std::string& pattern, Handler h) {
  routes_.emplace_back(method, std::regex(pattern));
  auto wrapped = [h = std::move(h)](const Request& req, Response& res) {
    try {
      h(req, res);
    } catch (const HttpError& e) {
      for (const auto& [name, value] : e.headers) res.set_header(name, value);
      sendError(res, e.status, e.what());
    } catch (const UsageError& e) {
      sendError(res, 400, e.what());
    } catch (const std::exception& e) {
      sendError(res, 500, e.what());
    }
  };
  if (method == "GET") http_.Get(pattern, wrapped);
  if (method == "POST") http_.Post(pattern, wrapped);
  if (method == "DELETE") http_.Delete(pattern, wrapped);
}

void Router::notFound(const Request& req, Response& res) const {
  std::vector<std::string> allowed;
  for (const auto& [m, re] : routes_)
    if (m != req.method && std::regex_match(req.path, re) && std::find(allowed.begin(), allowed.end(), m) == allowed.end())
      allowed.push_back(m);
  const std::string what = req.method + " " + utf8Prefix(req.path, 200);
  if (allowed.empty()) return sendError(res, 404, "no such path: " + what + " (docs/server.md lists the API)");
  res.set_header("Allow", joined(allowed));
  sendError(res, 405, what + ": expected " + joined(allowed));
}

}  // namespace substep::app::web
