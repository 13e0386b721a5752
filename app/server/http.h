// The HTTP plumbing of `substep serve` (app/server.h), apart from what any call means: errors as
// JSON answers, the checked fields of a request body, static files under a root with no way
// out of it, and the router that turns exceptions into answers and unrouted paths into 404/405.
#pragma once

#include "physics/utf8.h"

#include "physics/limits.h"
#include "physics/math.h"

#include <httplib.h>
#include <nlohmann/json.hpp>

#include <functional>
#include <regex>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace substep::app::web {

using json = nlohmann::json;
using httplib::Request;
using httplib::Response;

// A request that cannot be answered as asked: the status, the message of the JSON answer and any
// headers it carries (Retry-After).
struct HttpError : std::runtime_error {
  HttpError(int status, const std::string& message, std::vector<std::pair<std::string, std::string>> headers = {})
      : std::runtime_error(message), status(status), headers(std::move(headers)) {}
  int status;
  std::vector<std::pair<std::string, std::string>> headers;
};

// A value as a message quotes it: its JSON, cut short after limits::kMaxMessageValue bytes.
std::string quote(const json& v);
std::string joined(const std::vector<std::string>& v);

// The fields of a JSON request body, each checked where it is read; unknown fields are refused,
// so that a misspelt one is not silently ignored.
class Fields {
 public:
  Fields(const Request& req, const std::vector<std::string>& allowed);

  bool has(const std::string& k) const { return j_.contains(k) && !j_.at(k).is_null(); }
  const json& at(const std::string& k) const { return j_.at(k); }

  double number(const std::string& k, const Range& r) const { return numberOf(j_.at(k), k, r, false); }
  int integer(const std::string& k, const Range& r) const { return static_cast<int>(numberOf(j_.at(k), k, r, true)); }
  bool flag(const std::string& k) const;
  std::string text(const std::string& k, size_t maxLength = 1000) const;
  Vec3 vec3(const std::string& k, const Range& r) const;
  std::pair<double, double> pair(const std::string& k, const Range& r) const;

  static double numberOf(const json& v, const std::string& name, const Range& r, bool integer);

 private:
  json j_;
};

void sendJson(Response& res, const json& j, int status = 200);
// The largest JSON body Fields reads (413 beyond); the server's --max-body. Set once at start.
void setJsonBodyLimit(size_t bytes);
// {"error": message}, the message made valid UTF-8 whatever it quotes (a JSON parser's message
// quotes the bytes it read; other layers cut values after so many bytes), so that an error can
// always be answered: dump() throws on invalid UTF-8.
void sendError(Response& res, int status, const std::string& message);

// The Content-Type of a file served by its extension (".html"), nullptr for one not served.
const char* contentType(const std::string& ext);
// The file under `root` that `rel` names, or "" when it names none: no "..", no hidden or
// empty segment, no symlink anywhere on the way, a regular file inside the root.
std::string staticFile(const std::string& root, const std::string& rel);
// Answers with that file, or throws HttpError 404.
void serveFile(const std::string& root, const std::string& rel, Response& res);

// The routes of an httplib server: each handler's exceptions become JSON answers (HttpError its
// status, UsageError 400, anything else 500), and what no route answers is 404, or 405 naming
// the methods the path has.
class Router {
 public:
  using Handler = std::function<void(const Request&, Response&)>;
  // Answers unrouted requests and bodies over `maxBody` (413) in JSON.
  Router(httplib::Server& http, size_t maxBody);
  Router(const Router&) = delete;
  Router& operator=(const Router&) = delete;

  // method: GET, POST or DELETE; earlier routes are matched first.
  void add(const std::string& method, const std::string& pattern, Handler h);
  // No route for the method and path: 405 naming the methods the path has, else 404.
  void notFound(const Request& req, Response& res) const;

 private:
  httplib::Server& http_;
  std::vector<std::pair<std::string, std::regex>> routes_;
};

}  // namespace substep::app::web
