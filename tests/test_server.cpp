// substep serve's API (docs/server.md), through httplib's client against the built binary on a
// free loopback port: every call, bad parameters of every kind, path traversal, the session cap,
// expiry, a diverging session, SIGINT.
#include "physics/recording.h"
#include "physics/settings.h"
#include "render/image.h"
#include "run_substep.h"
#include "server_process.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <tuple>

using namespace substep_test;
namespace fs = std::filesystem;

namespace {

// Small frames: the tests look at behaviour, not pictures, and run under the sanitizers too.
const std::vector<std::string> kSmall = {"--size", "320x180", "--fps", "20"};

std::vector<std::string> small(std::vector<std::string> more = {}) {
  std::vector<std::string> a = kSmall;
  a.insert(a.end(), more.begin(), more.end());
  return a;
}

struct Answer {
  int status = -1;
  json body;
  std::string text, contentType;
};

Answer call(httplib::Client& c, const std::string& method, const std::string& path, const std::string& body = "") {
  httplib::Result r = method == "GET"      ? c.Get(path.c_str())
                      : method == "DELETE" ? c.Delete(path.c_str())
                                           : c.Post(path.c_str(), body, "application/json");
  Answer a;
  if (!r) return a;
  a.status = r->status;
  a.text = r->body;
  a.contentType = r->get_header_value("Content-Type");
  if (a.contentType.rfind("application/json", 0) == 0) a.body = json::parse(r->body, nullptr, false);
  return a;
}

Answer post(httplib::Client& c, const std::string& path, const json& body = json::object()) {
  return call(c, "POST", path, body.dump());
}

std::string create(httplib::Client& c, const json& body) {
  const Answer a = post(c, "/api/sessions", body);
  EXPECT_EQ(a.status, 201) << a.text;
  return a.body.value("id", "");
}

json stats(httplib::Client& c, const std::string& id) { return call(c, "GET", "/api/sessions/" + id + "/stats").body; }

// Waits (up to `seconds`) until the session's stats satisfy `ok`; returns the last stats.
json waitStats(httplib::Client& c, const std::string& id, const std::function<bool(const json&)>& ok, double seconds = 30) {
  json s;
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  do {
    s = stats(c, id);
    if (!s.is_discarded() && s.contains("panels") && ok(s)) return s;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  } while (std::chrono::steady_clock::now() < end);
  return s;
}

double simTime(const json& stats) {
  EXPECT_TRUE(stats.is_object() && stats.contains("panels") && !stats["panels"].empty()) << stats.dump();
  return stats.is_object() && stats.contains("panels") && !stats["panels"].empty() ? stats["panels"][0]["time"].get<double>()
                                                                                    : -1;
}

// The JPEG parts of an MJPEG capture.
std::vector<std::string> jpegParts(const std::string& stream) {
  std::vector<std::string> parts;
  size_t p = 0;
  while ((p = stream.find("Content-Length: ", p)) != std::string::npos) {
    const size_t n = std::stoul(stream.substr(p + 16));
    const size_t start = stream.find("\r\n\r\n", p);
    if (start == std::string::npos || start + 4 + n > stream.size()) break;
    parts.push_back(stream.substr(start + 4, n));
    p = start + 4 + n;
  }
  return parts;
}

}  // namespace

TEST(Server, PageScenesAndMethods) {
  ServerProcess srv(small());
  auto c = srv.client();
  Answer page = call(*c, "GET", "/");
  EXPECT_EQ(page.status, 200);
  EXPECT_EQ(page.contentType, "text/html; charset=utf-8");
  EXPECT_NE(page.text.find("<title>substep</title>"), std::string::npos);
  for (const char* f : {"/app.js", "/plot.js", "/style.css", "/index.html"}) EXPECT_EQ(call(*c, "GET", f).status, 200) << f;

  const Answer scenes = call(*c, "GET", "/api/scenes");
  ASSERT_EQ(scenes.status, 200);
  std::vector<std::string> names;
  for (const json& s : scenes.body["scenes"]) names.push_back(s["name"]);
  for (const char* n : {"pyramid", "stack", "chain", "ragdoll_pile"})
    EXPECT_NE(std::find(names.begin(), names.end(), n), names.end()) << n;
  const json pyramid = *std::find_if(scenes.body["scenes"].begin(), scenes.body["scenes"].end(),
                                     [](const json& s) { return s["name"] == "pyramid"; });
  EXPECT_EQ(pyramid["bodies"], 210);

  const Answer methods = call(*c, "GET", "/api/methods");
  ASSERT_EQ(methods.status, 200);
  EXPECT_EQ(methods.body["algorithms"].size(), 6u);
  bool kappa = false;
  for (const json& s : methods.body["settings"])
    if (s["key"] == "kappa") {
      kappa = true;
      EXPECT_EQ(s["alias"], "κ");
      EXPECT_EQ(s["expected"], "a number in (0, 10]");  // the table's range, as the command line says it
      EXPECT_EQ(s["range"]["max"], 10);
    }
  EXPECT_TRUE(kappa);
  // The schema whole: every setting once, with which algorithms read it and a default for each.
  ASSERT_EQ(methods.body["settings"].size(), substep::settingTable().size());
  for (const substep::SettingSpec& spec : substep::settingTable()) {
    const json& s = methods.body["settings"][spec.index];
    EXPECT_EQ(s["key"], spec.key);
    EXPECT_FALSE(s["takes"].empty()) << spec.key;
    EXPECT_EQ(s["defaults"].size(), 6u) << spec.key;
  }
  const Answer server = call(*c, "GET", "/api/server");
  EXPECT_EQ(server.body["max_sessions"], 8);
  EXPECT_EQ(server.body["size"], "320x180");
  EXPECT_EQ(call(*c, "GET", "/api/lab").body["files"], json::array());
}

TEST(Server, StaticFilesRefuseTraversal) {
  // A copy of the page with a symlink out of it, a symlinked folder and a hidden file.
  const fs::path web = emptyScratchFolder("test_server") / "web";
  fs::create_directories(web);
  for (const auto& e : fs::directory_iterator(fs::path(SUBSTEP_SOURCE_DIR) / "assets/web")) fs::copy(e.path(), web / e.path().filename());
  fs::create_symlink("/etc/passwd", web / "leak.txt");
  fs::create_directory_symlink("/etc", web / "etc");
  std::ofstream(web / ".secret.txt") << "root:hidden";
  ServerProcess srv(small({"--web", web.string()}));

  const std::vector<std::string> attempts = {
      "/../../etc/passwd",        "/%2e%2e/%2e%2e/etc/passwd", "/%2E%2E/%2E%2E/etc/passwd", "/..%2f..%2fetc%2fpasswd",
      "/..%252f..%252fetc/passwd", "//etc/passwd",             "/etc/passwd",               "/leak.txt",
      "/etc/passwd%00.html",      "/.secret.txt",              "/./index.html/../../../etc/passwd",
      "/lab/../../etc/passwd",    "/%2e%2e%2f%2e%2e%2fetc%2fpasswd", "/..\\..\\etc\\passwd", "/etc/hostname"};
  for (const std::string& path : attempts) {
    const std::string r = rawRequest(srv.port(), "GET " + path + " HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
    const int st = rawStatus(r);
    EXPECT_TRUE(st == 400 || st == 404) << path << " -> " << st;
    EXPECT_EQ(r.find("root:"), std::string::npos) << path;
  }
  // An absolute URI is not a way out either.
  const std::string r = rawRequest(srv.port(), "GET http://x/../../etc/passwd HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
  EXPECT_EQ(r.find("root:"), std::string::npos);
  // The page itself is still there.
  EXPECT_EQ(rawStatus(rawRequest(srv.port(), "GET /index.html HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")), 200);
  EXPECT_EQ(rawStatus(rawRequest(srv.port(), "GET /%61pp.js HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")), 200);
}

TEST(Server, SessionLifecycle) {
  ServerProcess srv(small());
  auto c = srv.client();
  const Answer made = post(*c, "/api/sessions", {{"scene", "stack"}});
  ASSERT_EQ(made.status, 201) << made.text;
  const std::string id = made.body["id"];
  EXPECT_EQ(id.size(), 16u);
  EXPECT_EQ(made.body["scene"], "stack");
  EXPECT_EQ(made.body["width"], 320);
  EXPECT_EQ(made.body["playing"], false);
  EXPECT_EQ(made.body["panels"][0]["settings"]["algorithm"], "a2");  // the scene's solver block
  for (const substep::SettingSpec& spec : substep::settingTable())  // every resolved setting, by its key
    EXPECT_EQ(made.body["panels"][0]["settings"].contains(spec.key), spec.resolved()) << spec.key;
  EXPECT_EQ(call(*c, "GET", "/api/sessions/" + id).status, 200);
  EXPECT_EQ(call(*c, "GET", "/api/server").body["sessions"], 1);
  const Answer gone = call(*c, "DELETE", "/api/sessions/" + id);
  EXPECT_EQ(gone.status, 200);
  const Answer after = call(*c, "GET", "/api/sessions/" + id);
  EXPECT_EQ(after.status, 404);
  EXPECT_NE(after.body["error"].get<std::string>().find("no session \"" + id + "\""), std::string::npos);
  for (const std::string bad : {"0123456789abcdef", "nope", "..%2f..", "0123456789ABCDEF"}) {
    EXPECT_EQ(call(*c, "GET", "/api/sessions/" + bad).status, 404) << bad;
    EXPECT_EQ(post(*c, "/api/sessions/" + bad + "/play").status, 404) << bad;
    EXPECT_EQ(call(*c, "DELETE", "/api/sessions/" + bad).status, 404) << bad;
    EXPECT_EQ(call(*c, "GET", "/api/sessions/" + bad + "/stream.mjpeg").status, 404) << bad;
  }
  // The beacon a closing page sends.
  const std::string id2 = create(*c, {{"scene", "stack"}});
  EXPECT_EQ(post(*c, "/api/sessions/" + id2 + "/close").status, 200);
  EXPECT_EQ(call(*c, "GET", "/api/sessions/" + id2).status, 404);
}

TEST(Server, BadParametersNameTheParameter) {
  ServerProcess srv(small());
  auto c = srv.client();
  const std::string a5 = create(*c, {{"scene", "pyramid"}});  // a5 by the scene's solver block
  const std::string a2 = create(*c, {{"scene", "box_on_ground"}});
  const std::string s5 = "/api/sessions/" + a5, s2 = "/api/sessions/" + a2;
  struct Case {
    std::string path, body, expect;
    int status = 400;
  };
  const std::vector<Case> cases = {
      // creating
      {"/api/sessions", "{}", "scene: expected a scene name"},
      {"/api/sessions", R"({"scene": "nope"})", "scene: expected one of box_on_ground, chain"},
      {"/api/sessions", R"({"scene": "../../etc/passwd"})", "scene: expected one of"},
      {"/api/sessions", R"({"scene": 5})", "scene: expected a string, got 5"},
      {"/api/sessions", R"({"scene": "stack", "size": "10x10"})", "size: expected WIDTHxHEIGHT from 64x64 to 1920x1080"},
      {"/api/sessions", R"({"scene": "stack", "size": "big"})", "size: expected WIDTHxHEIGHT"},
      {"/api/sessions", R"({"scene": "stack", "fps": 0})", "fps: expected an integer in [1, 60], got 0"},
      {"/api/sessions", R"({"scene": "stack", "fps": "30"})", "fps: expected an integer in [1, 60], got \"30\""},
      {"/api/sessions", R"({"scene": "stack", "speed": 1e400})", "body: expected a JSON object"},
      {"/api/sessions", R"({"scene": "stack", "method": "a9"})", "method: \"a9\": unknown algorithm"},
      {"/api/sessions", R"({"scene": "stack", "method": "a2,a5"})", "method: expected one method"},
      {"/api/sessions", R"({"scene": "stack", "methods": "a1,a2,a3,a4,a5"})", "methods: expected 1 to 4 methods, got 5"},
      {"/api/sessions", R"({"scene": "stack", "methods": "a5:n=0"})", "methods: \"a5:n=0\": n: expected an integer in [1, 1000], got \"0\""},
      {"/api/sessions", R"({"scene": "stack", "bogus": 1})", "unknown field \"bogus\"; expected one of scene"},
      {"/api/sessions", "not json", "body: expected a JSON object"},
      {"/api/sessions", "[1, 2]", "body: expected a JSON object, got [1,2]"},
      // settings: the table's ranges and messages
      {s5 + "/settings", R"({"settings": {"kappa": 11}})", "settings.kappa: expected a number in (0, 10], got 11"},
      {s5 + "/settings", R"({"settings": {"kappa": 0}})", "settings.kappa: expected a number in (0, 10], got 0"},
      {s5 + "/settings", R"({"settings": {"n": 0}})", "settings.n: expected an integer in [1, 1000], got 0"},
      {s5 + "/settings", R"({"settings": {"n": 2.5}})", "settings.n: expected an integer in [1, 1000], got 2.5"},
      {s5 + "/settings", R"({"settings": {"n": "many"}})", "settings.n: expected an integer in [1, 1000], got \"many\""},
      {s5 + "/settings", R"({"settings": {"tau": -1}})", "settings.tau: expected a number in [0, 10], got -1"},
      {s5 + "/settings", R"({"settings": {"dt": 2}})", "settings.dt: expected a number in [1e-6, 1], got 2"},
      {s5 + "/settings", R"({"settings": {"warm": "maybe"}})", "settings.warm: expected on or off, got \"maybe\""},
      {s5 + "/settings", R"({"settings": {"omega": true}})", "settings.omega: expected a number in (0, 2), got true"},
      {s5 + "/settings", R"({"settings": {"algorithm": "a9"}})", "settings.algorithm: expected one of a1, a2, a3, a4, a5, soft"},
      {s5 + "/settings", R"({"settings": {"preset": "9-hard"}})", "settings.preset: expected one of 2-soft"},
      {s5 + "/settings", R"({"settings": {"foo": 1}})", "settings.foo: unknown setting; expected one of algorithm, h, n, m"},
      {s5 + "/settings", R"({"settings": {"n": [4]}})", "settings.n: expected an integer in [1, 1000], got [4]"},
      {s5 + "/settings", R"({"settings": 5})", "settings: expected an object"},
      {s5 + "/settings", R"({"panel": 1, "settings": {"n": 4}})", "panel: expected an integer in [0, 0], got 1"},
      {s5 + "/settings", R"({"method": "a5:kappa=0"})", "method: \"a5:kappa=0\": kappa: expected a number in (0, 10]"},
      {s5 + "/settings", R"({})", "method, settings: give a method or settings"},
      {s2 + "/settings", R"({"settings": {"kappa": 0.9}})", "--kappa: a2 does not use it (a3, a4, a5 do)"},
      {s2 + "/settings", R"({"settings": {"n": 4}})", "--substeps: a2 does not use it"},
      // panels and scene
      {s5 + "/panels", R"({"methods": ""})", "methods: an empty method"},
      {s5 + "/panels", R"({"methods": [1]})", "methods: expected method specs as strings, got 1"},
      {s5 + "/panels", R"({"methods": "a2,a2,a2,a2,a2"})", "methods: expected 1 to 4 methods, got 5"},
      {s5 + "/panels", R"({})", "methods: expected 1 to 4 methods"},
      {s5 + "/scene", R"({"scene": "nope"})", "scene: expected one of"},
      // camera
      {s5 + "/camera", R"({"pitch": 100})", "pitch: expected a number in [-89, 89], got 100"},
      {s5 + "/camera", R"({"distance": -1})", "distance: expected a number in [0.001, 100000], got -1"},
      {s5 + "/camera", R"({"yaw": "north"})", "yaw: expected a number in [-100000, 100000], got \"north\""},
      {s5 + "/camera", R"({"target": [1, 2]})", "target: expected [x, y, z], got [1,2]"},
      {s5 + "/camera", R"({"target": [1, 2, "x"]})", "target[2]: expected a number"},
      {s5 + "/camera", R"({"preset": "nope"})", "preset: expected one of default, oblique, fitted, got \"nope\""},
      {s5 + "/camera", R"({"follow": "nobody"})", "follow: expected the name of a dynamic body of pyramid"},
      {s5 + "/camera", R"({"follow": "ground"})", "follow: expected the name of a dynamic body"},
      {s5 + "/camera", R"({"zoom": 0})", "zoom: expected a number in [0.01, 100], got 0"},
      {s5 + "/camera", R"({"rotate": [1]})", "rotate: expected [a, b], got [1]"},
      {s5 + "/camera", R"({"pan": [1, 1e9]})", "pan[1]: expected a number in [-10000, 10000]"},
      {s5 + "/camera", R"({"fov": 1})", "fov: expected a number in [5, 150], got 1"},
      // view
      {s5 + "/view", R"({"colour": "purple"})", "colour: expected auto, body, group, speed, activity or error, got \"purple\""},
      {s5 + "/view", R"({"contacts": "yes"})", "contacts: expected true or false, got \"yes\""},
      {s5 + "/view", R"({"highlight": ["nobody"]})", "highlight: expected names of bodies of pyramid, got \"nobody\""},
      // play state
      {s5 + "/play", R"({"speed": 0})", "speed: expected 0.01 to 10 simulated seconds per second (negative: backwards), got 0"},
      {s5 + "/play", R"({"speed": 100})", "speed: expected a number in [-10, 10], got 100"},
      {s5 + "/pause", R"({"now": true})", "unknown field \"now\"; expected none"},
      {s5 + "/step", R"({"count": 0})", "count: expected 1 to 600 steps, negative to go back"},
      {s5 + "/step", R"({"count": 601})", "count: expected an integer in [-600, 600], got 601"},
      {s5 + "/step", R"({"count": 1.5})", "count: expected an integer in [-600, 600], got 1.5"},
      {s5 + "/seek", R"({"time": -1})", "time: expected a number in [0, 3600], got -1"},
      {s5 + "/seek", R"({})", "time: expected a number in [0, 3600]"},
      // picking and pushing
      {s5 + "/pick", R"({"x": -1, "y": 0})", "x: expected a number in [0, 320), got -1"},
      {s5 + "/pick", R"({"x": 320, "y": 0})", "x: expected a number in [0, 320), got 320"},
      {s5 + "/pick", R"({"x": 0, "y": 180})", "y: expected a number in [0, 180), got 180"},
      {s5 + "/pick", R"({})", "x, y: expected the pixel of the frame"},
      {s5 + "/push", R"({"x": 1, "y": 1, "speed": 0})", "speed: expected a number in (0, 100], got 0"},
      {s5 + "/push", R"({"body": "ground", "impulse": [0, 1, 0]})", "body: expected the name of a dynamic body of pyramid, got \"ground\""},
      {s5 + "/push", R"({"body": "nobody", "impulse": [0, 1, 0]})", "body: expected the name of a dynamic body"},
      {s2 + "/push", R"({"body": "box"})", "impulse: expected [x, y, z] in N s"},
      {s2 + "/push", R"({"body": "box", "impulse": [0, 1e10, 0]})", "impulse[1]: expected a number in [-1e9, 1e9]"},
      {s2 + "/push", R"({"body": "box", "impulse": [0, 1, 0], "x": 3})", "body: give body and impulse, or x and y, not both"},
      // clips
      {s5 + "/clips", R"({"mode": "sideways"})", "mode: expected last or next, got \"sideways\""},
      {s5 + "/clips", R"({"seconds": 0})", "seconds: expected a number in [0.1, 10], got 0"},
      {s5 + "/clips", R"({"mode": "next", "seconds": 1000})", "seconds: expected a number in [0.1, 60], got 1000"},
      {s5 + "/clips", R"({"mode": "last"})", "no frames were drawn in the last", 409},
  };
  for (const Case& k : cases) {
    const Answer a = call(*c, "POST", k.path, k.body);
    EXPECT_EQ(a.status, k.status) << k.path << " " << k.body << " -> " << a.text;
    ASSERT_TRUE(a.body.is_object()) << k.path << " " << k.body << " -> " << a.text;
    const std::string error = a.body.value("error", "");
    EXPECT_NE(error.find(k.expect), std::string::npos) << k.path << " " << k.body << "\n  got:    " << error
                                                       << "\n  wanted: " << k.expect;
  }
  // Nothing of the refused requests changed the session.
  const json st = call(*c, "GET", s5).body;
  EXPECT_EQ(st["panels"].size(), 1u);
  EXPECT_EQ(st["panels"][0]["settings"]["kappa"], 0.85);
  EXPECT_EQ(st["panels"][0]["settings"]["substeps"], 4);
  EXPECT_EQ(st["camera"]["pitch"], call(*c, "GET", s5).body["camera"]["pitch"]);
  // Other methods and paths: 405 with Allow, 404, both in JSON.
  const Answer wrongMethod = call(*c, "GET", "/api/sessions");
  EXPECT_EQ(wrongMethod.status, 405);
  EXPECT_NE(wrongMethod.body.value("error", "").find("expected POST"), std::string::npos);
  EXPECT_EQ(call(*c, "DELETE", "/api/scenes").status, 405);
  EXPECT_EQ(call(*c, "GET", s5 + "/play").status, 405);
  const Answer unknown = call(*c, "GET", "/api/nothing");
  EXPECT_EQ(unknown.status, 404);
  EXPECT_NE(unknown.body.value("error", "").find("no such path"), std::string::npos);
  EXPECT_EQ(call(*c, "GET", s5 + "/clips/99").status, 404);
  EXPECT_EQ(call(*c, "GET", s5 + "/clips/99.mp4").status, 404);
  // Bodies over the cap: 413.
  const Answer big = call(*c, "POST", "/api/sessions", R"({"scene": ")" + std::string(100000, 'x') + "\"}");
  EXPECT_EQ(big.status, 413);
}

// Bodies that are not a JSON object of the call (random bytes, NUL bytes, invalid UTF-8 in and out
// of strings and keys, truncated JSON, long non-ASCII names that a message cuts short) are 400 at
// every POST endpoint, with a JSON body (so valid UTF-8) naming the problem; never 500. Paths with
// such bytes are 404 or 405 in JSON. A fixed seed: the same requests every run.
TEST(Server, BadBodiesAreRefusedAt400) {
  ServerProcess srv(small());
  auto c = srv.client();
  const std::string s = "/api/sessions/" + create(*c, {{"scene", "pyramid"}});
  // Every POST endpoint with a body, with the fields it reads. POST .../close reads no body: what
  // a closing page's beacon sends closes the session whatever it holds.
  const std::vector<std::pair<std::string, std::vector<std::string>>> endpoints = {
      {"/api/sessions", {"scene", "method", "methods", "size", "fps", "play", "speed"}},
      {s + "/settings", {"panel", "method", "settings"}},
      {s + "/panels", {"methods"}},
      {s + "/scene", {"scene", "methods"}},
      {s + "/camera", {"preset", "yaw", "pitch", "distance", "fov", "target", "follow", "orbit", "rotate", "zoom", "pan"}},
      {s + "/view",
       {"colour", "color", "contacts", "joints", "hud", "speed_scale", "error_scale", "highlight", "forces",
        "joint_errors", "force_scale"}},
      {s + "/play", {"speed"}},
      {s + "/pause", {}},
      {s + "/step", {"count"}},
      {s + "/reset", {}},
      {s + "/seek", {"time"}},
      {s + "/pick", {"x", "y"}},
      {s + "/push", {"x", "y", "speed", "body", "impulse", "point"}},
      {s + "/clips", {"mode", "seconds"}},
  };
  std::mt19937 rng(20240521);
  const auto below = [&](size_t n) { return static_cast<size_t>(rng() % n); };
  const auto bytes = [&](size_t n, bool anyByte) {
    std::string b;
    for (size_t i = 0; i < n; ++i) b += static_cast<char>(anyByte ? below(256) : 0x20 + below(0x5f));
    return b;
  };
  const std::vector<std::string> notUtf8 = {"\xff", "\xfe", "\xc0\xaf", "\xc3\x28", "\xe2\x82", "\xed\xa0\x80",
                                            "\xf4\x90\x80\x80", "\x80", "\xf8\x88\x80\x80\x80"};
  const auto bad = [&] { return notUtf8[below(notUtf8.size())]; };
  // A few "a" and then two- and three-byte characters: a message that cuts it after so many
  // bytes may cut one in half.
  const auto longName = [&] {
    std::string n(1 + below(3), 'a');
    for (size_t i = 0, k = 40 + below(40); i < k; ++i) n += i % 2 ? "\xc3\xa9" : "\xe2\x82\xac";
    return n;
  };
  const auto body = [&](const std::vector<std::string>& fields) -> std::string {
    const std::string field = fields.empty() ? "speed" : fields[below(fields.size())];
    const json valid = {{field, json::array({1, "x", {{"k", 2.5}}})}};
    switch (below(8)) {
      case 0: {  // random bytes with a NUL: never JSON
        std::string b = bytes(1 + below(80), true);
        b.insert(below(b.size() + 1), 1, '\0');
        return b;
      }
      case 1: {  // random bytes with a byte that is never UTF-8
        std::string b = bytes(1 + below(80), true);
        return b.insert(below(b.size() + 1), "\xff");
      }
      case 2: {  // JSON cut short
        const std::string j = valid.dump();
        return j.substr(0, 1 + below(j.size() - 1));
      }
      case 3:  // invalid UTF-8 in a string value
        return "{\"" + field + "\": \"" + bytes(below(10), false) + bad() + bytes(below(10), false) + "\"}";
      case 4:  // invalid UTF-8 in a key
        return "{\"" + bytes(below(5), false) + bad() + "\": 1}";
      case 5:  // valid JSON, a long non-ASCII key: an unknown field
        return json{{longName(), 1}}.dump();
      case 6:  // valid JSON, a long non-ASCII string where the field wants something else
        return json{{field, longName()}}.dump();
      default: {  // valid JSON with a NUL or invalid UTF-8 after it
        std::string j = valid.dump();
        return j.insert(below(j.size() + 1), below(2) ? std::string(1, '\0') : bad());
      }
    }
  };
  int requests = 0, refused = 0;
  for (int round = 0; round < 24; ++round)
    for (const auto& [path, fields] : endpoints) {
      const std::string b = body(fields);
      const Answer a = call(*c, "POST", path, b);
      ++requests;
      std::string shown;  // the body, bytes outside printable ASCII as \xNN
      for (unsigned char ch : b) {
        char hex[8];
        std::snprintf(hex, sizeof hex, "\\x%02x", ch);
        shown += ch >= 0x20 && ch < 0x7f ? std::string(1, static_cast<char>(ch)) : std::string(hex);
      }
      const bool ok = a.status == 400 && a.body.is_object() && a.body.contains("error") && a.body["error"].is_string() &&
                      !a.body["error"].get<std::string>().empty();
      refused += ok;
      EXPECT_TRUE(ok) << path << " " << shown << " -> " << a.status << " " << a.text.substr(0, 300);
    }
  EXPECT_EQ(refused, requests) << "of " << requests << " bad bodies, " << requests - refused << " not answered 400 with an error";
  // Ids and paths that are not UTF-8, which the answers quote: 404 or 405 in JSON (the 405 comes
  // from httplib's error handler, where a throw would end the server).
  const std::vector<std::tuple<std::string, std::string, int>> paths = {
      {"POST", "/api/sessions/%ff%fe", 404}, {"POST", "/api/sessions/a%c3%28/play", 404}, {"GET", "/api/x%ff", 404},
      {"GET", "/%ff.html", 404},             {"POST", "/api/x%ff", 405},                  {"DELETE", "/%c3", 405}};
  for (const auto& [method, path, status] : paths) {
    const Answer a = call(*c, method, path, "{}");
    EXPECT_EQ(a.status, status) << method << " " << path << " -> " << a.text;
    EXPECT_TRUE(a.body.is_object() && !a.body.value("error", "").empty()) << method << " " << path << " -> " << a.text;
  }
  // The session lived through it, unchanged.
  const Answer st = call(*c, "GET", s);
  ASSERT_EQ(st.status, 200);
  EXPECT_EQ(st.body["panels"].size(), 1u);
  EXPECT_EQ(st.body["time"], 0);
}

TEST(Server, PlayPauseStepSeekReset) {
  ServerProcess srv(small());
  auto c = srv.client();
  const std::string id = create(*c, {{"scene", "stack"}});
  const std::string s = "/api/sessions/" + id;
  EXPECT_DOUBLE_EQ(simTime(stats(*c, id)), 0);
  const Answer stepped = post(*c, s + "/step", {{"count", 3}});
  ASSERT_EQ(stepped.status, 200) << stepped.text;
  EXPECT_NEAR(stepped.body["time"].get<double>(), 3.0 / 60, 1e-9);
  EXPECT_EQ(stepped.body["playing"], false);

  ASSERT_EQ(post(*c, s + "/seek", {{"time", 2.0}}).status, 200);
  json st = waitStats(*c, id, [](const json& j) { return !j["seeking"].get<bool>() && simTime(j) > 1.9; });
  EXPECT_NEAR(simTime(st), 2.0, 1.0 / 60);
  EXPECT_FALSE(st["playing"].get<bool>());
  ASSERT_EQ(post(*c, s + "/seek", {{"time", 0.5}}).status, 200);  // back: from the start
  st = waitStats(*c, id, [](const json& j) { return !j["seeking"].get<bool>() && simTime(j) < 0.6; });
  EXPECT_NEAR(simTime(st), 0.5, 1.0 / 60);

  ASSERT_EQ(post(*c, s + "/play", {{"speed", 2}}).status, 200);
  st = waitStats(*c, id, [](const json& j) { return simTime(j) > 1.0; });
  EXPECT_GT(simTime(st), 1.0);
  EXPECT_TRUE(st["playing"].get<bool>());
  EXPECT_EQ(st["speed"], 2);
  ASSERT_EQ(post(*c, s + "/pause").status, 200);
  const double paused = simTime(waitStats(*c, id, [](const json& j) { return !j["playing"].get<bool>(); }));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_DOUBLE_EQ(simTime(stats(*c, id)), paused);
  const Answer reset = post(*c, s + "/reset");
  EXPECT_EQ(reset.body["time"], 0);
}

TEST(Server, SettingsPanelsAndSceneChange) {
  ServerProcess srv(small());
  auto c = srv.client();
  const std::string id = create(*c, {{"scene", "pyramid"}});
  const std::string s = "/api/sessions/" + id;
  ASSERT_EQ(post(*c, s + "/step", {{"count", 2}}).status, 200);
  Answer a = post(*c, s + "/settings", {{"settings", {{"n", 8}, {"kappa", 0.9}, {"warm", false}}}});
  ASSERT_EQ(a.status, 200) << a.text;
  const json& set = a.body["panels"][0]["settings"];
  EXPECT_EQ(set["algorithm"], "a5");
  EXPECT_EQ(set["substeps"], 8);
  EXPECT_EQ(set["kappa"], 0.9);
  EXPECT_EQ(set["warm_start"], false);
  EXPECT_EQ(set["tau"], 0);  // the scene's, kept
  EXPECT_EQ(set["sleep"], true);  // serve's default: islands at rest sleep
  EXPECT_NEAR(a.body["time"].get<double>(), 2.0 / 60, 1e-9);  // changed while it runs: goes on from its state
  a = post(*c, s + "/settings", {{"method", "a2:m=20:omega=1.3"}});
  ASSERT_EQ(a.status, 200) << a.text;
  EXPECT_EQ(a.body["panels"][0]["settings"]["algorithm"], "a2");
  EXPECT_EQ(a.body["panels"][0]["settings"]["iterations"], 20);
  EXPECT_EQ(a.body["panels"][0]["settings"]["omega"], 1.3);
  a = post(*c, s + "/settings", {{"settings", {{"algorithm", "a4"}, {"tau", 0.3}}}});
  ASSERT_EQ(a.status, 200) << a.text;
  EXPECT_EQ(a.body["panels"][0]["settings"]["algorithm"], "a4");
  EXPECT_EQ(a.body["panels"][0]["settings"]["tau"], 0.3);
  a = post(*c, s + "/settings", {{"settings", {{"preset", "8-hard"}}}});
  ASSERT_EQ(a.status, 200) << a.text;
  EXPECT_EQ(a.body["panels"][0]["settings"]["substeps"], 8);

  // Side by side: 2 to 4 panels, each its own method; settings to one panel.
  a = post(*c, s + "/panels", {{"methods", "a2:m=4,a5:n=4"}});
  ASSERT_EQ(a.status, 200) << a.text;
  ASSERT_EQ(a.body["panels"].size(), 2u);
  EXPECT_EQ(a.body["panels"][0]["settings"]["algorithm"], "a2");
  EXPECT_EQ(a.body["panels"][1]["settings"]["algorithm"], "a5");
  EXPECT_EQ(a.body["time"], 0);
  a = post(*c, s + "/settings", {{"panel", 1}, {"settings", {{"n", 2}}}});
  ASSERT_EQ(a.status, 200) << a.text;
  EXPECT_EQ(a.body["panels"][1]["settings"]["substeps"], 2);
  EXPECT_EQ(a.body["panels"][0]["settings"]["iterations"], 4);
  a = post(*c, s + "/panels", {{"methods", json::array({"a3", "a4", "a5", "soft"})}});
  EXPECT_EQ(a.body["panels"].size(), 4u);
  EXPECT_EQ(stats(*c, id)["panels"].size(), 4u);  // the stats follow the change at once
  const Answer frame = call(*c, "GET", s + "/frame.png");
  ASSERT_EQ(frame.status, 200);
  const auto img = substep::render::decodePng(std::vector<uint8_t>(frame.text.begin(), frame.text.end()));
  EXPECT_EQ(img.width, 320);
  EXPECT_EQ(img.height, 180);

  a = post(*c, s + "/scene", {{"scene", "chain"}});
  ASSERT_EQ(a.status, 200) << a.text;
  EXPECT_EQ(a.body["scene"], "chain");
  EXPECT_EQ(a.body["panels"].size(), 4u);
  EXPECT_EQ(a.body["panels"][0]["settings"]["algorithm"], "a2");  // the chain's own solver block
  a = post(*c, s + "/scene", {{"scene", "stack"}, {"methods", "a5:n=4"}});
  EXPECT_EQ(a.body["panels"].size(), 1u);
  EXPECT_EQ(a.body["panels"][0]["settings"]["algorithm"], "a5");
}

// Sleeping is serve's default unless the scene or the page says otherwise; --no-sleep keeps every
// island awake. A settled stack's bodies come out asleep in the state (the page colours them).
TEST(Server, SleepIsServesDefaultAndNoSleepTurnsItOff) {
  for (const bool on : {true, false}) {
    std::vector<std::string> args = small();
    if (!on) args.push_back("--no-sleep");
    ServerProcess srv(args);
    auto c = srv.client();
    const std::string id = create(*c, {{"scene", "stack"}});
    const std::string s = "/api/sessions/" + id;
    Answer a = post(*c, s + "/step", {{"count", 120}});
    ASSERT_EQ(a.status, 200) << a.text;
    a = call(*c, "GET", s);
    ASSERT_EQ(a.status, 200) << a.text;
    EXPECT_EQ(a.body["panels"][0]["settings"]["sleep"], on) << a.text;
    a = post(*c, s + "/settings", {{"settings", {{"sleep", !on}}}});  // the page's choice wins
    ASSERT_EQ(a.status, 200) << a.text;
    EXPECT_EQ(a.body["panels"][0]["settings"]["sleep"], !on);
  }
}

TEST(Server, CameraAndView) {
  ServerProcess srv(small());
  auto c = srv.client();
  const std::string s = "/api/sessions/" + create(*c, {{"scene", "stack"}});
  const json cam0 = call(*c, "GET", s).body["camera"];
  EXPECT_EQ(cam0["preset"], "default");
  json cam = post(*c, s + "/camera", {{"rotate", {10, 5}}, {"zoom", 0.5}}).body["camera"];
  EXPECT_DOUBLE_EQ(cam["yaw"].get<double>(), cam0["yaw"].get<double>() + 10);
  EXPECT_DOUBLE_EQ(cam["pitch"].get<double>(), cam0["pitch"].get<double>() + 5);
  EXPECT_DOUBLE_EQ(cam["distance"].get<double>(), cam0["distance"].get<double>() * 0.5);
  cam = post(*c, s + "/camera", {{"rotate", {0, 200}}}).body["camera"];
  EXPECT_EQ(cam["pitch"], 89);  // clamped, not refused: a drag past the pole
  cam = post(*c, s + "/camera", {{"pan", {100, 0}}}).body["camera"];
  EXPECT_NE(cam["target"], cam0["target"]);
  cam = post(*c, s + "/camera", {{"preset", "side"}}).body["camera"];
  EXPECT_EQ(cam["preset"], "side");
  EXPECT_EQ(cam["yaw"], 0);
  cam = post(*c, s + "/camera", {{"preset", "fitted"}}).body["camera"];
  EXPECT_EQ(cam["preset"], "fitted");
  cam = post(*c, s + "/camera", {{"follow", "stack_4"}, {"orbit", 30}, {"yaw", 45}, {"distance", 7}, {"fov", 60}}).body["camera"];
  EXPECT_EQ(cam["follow"], "stack_4");
  EXPECT_EQ(cam["orbit"], 30);
  EXPECT_EQ(cam["fov"], 60);
  cam = post(*c, s + "/camera", {{"target", {1, 2, 3}}}).body["camera"];
  EXPECT_EQ(cam["target"], json({1, 2, 3}));
  EXPECT_EQ(cam["follow"], "");
  const json view = post(*c, s + "/view", {{"colour", "speed"}, {"contacts", true}, {"joints", true}, {"hud", false},
                                           {"speed_scale", 2}, {"highlight", {"stack_0"}}})
                        .body["view"];
  EXPECT_EQ(view["colour"], "speed");
  EXPECT_EQ(view["contacts"], true);
  EXPECT_EQ(view["hud"], false);
  EXPECT_EQ(view["speed_scale"], 2);
  EXPECT_EQ(view["forces"], false);
  const json forces =
      post(*c, s + "/view", {{"forces", true}, {"joint_errors", true}, {"force_scale", 0.5}}).body["view"];
  EXPECT_EQ(forces["forces"], true);
  EXPECT_EQ(forces["joint_errors"], true);
  EXPECT_EQ(forces["force_scale"], 0.5);
  EXPECT_EQ(forces["colour"], "speed");  // the other fields stay
  const Answer negative = post(*c, s + "/view", {{"force_scale", -1}});
  EXPECT_EQ(negative.status, 400) << negative.text;
  EXPECT_NE(negative.text.find("force_scale"), std::string::npos) << negative.text;
}

TEST(Server, PickAndPush) {
  ServerProcess srv(small());
  auto c = srv.client();
  const std::string id = create(*c, {{"scene", "box_on_ground"}});
  const std::string s = "/api/sessions/" + id;
  // The default camera looks at the box: the centre pixel is on it, a top corner is sky.
  Answer hit = post(*c, s + "/pick", {{"x", 160}, {"y", 90}});
  ASSERT_EQ(hit.status, 200) << hit.text;
  EXPECT_EQ(hit.body["hit"], true);
  EXPECT_EQ(hit.body["name"], "box");
  EXPECT_EQ(hit.body["panel"], 0);
  const Answer miss = post(*c, s + "/pick", {{"x", 2}, {"y", 2}});
  EXPECT_EQ(miss.body["hit"], false);
  EXPECT_EQ(post(*c, s + "/push", {{"x", 2}, {"y", 2}}).body["hit"], false);

  ASSERT_EQ(post(*c, s + "/step", {{"count", 5}}).status, 200);
  EXPECT_LT(stats(*c, id)["panels"][0]["kinetic"].get<double>(), 1e-3);  // at rest
  const Answer pushed = post(*c, s + "/push", {{"x", 160}, {"y", 90}, {"speed", 5}});
  ASSERT_EQ(pushed.status, 200) << pushed.text;
  EXPECT_EQ(pushed.body["name"], "box");
  EXPECT_NEAR(pushed.body["impulse"][0].get<double>() * pushed.body["impulse"][0].get<double>() +
                  pushed.body["impulse"][1].get<double>() * pushed.body["impulse"][1].get<double>() +
                  pushed.body["impulse"][2].get<double>() * pushed.body["impulse"][2].get<double>(),
              25.0, 1e-6);  // 1 kg at 5 m/s
  ASSERT_EQ(post(*c, s + "/step").status, 200);
  EXPECT_GT(waitStats(*c, id, [](const json& j) { return j["panels"][0]["steps"] == 6; })["panels"][0]["kinetic"].get<double>(), 1.0);

  // A given impulse on a named body, in every panel of a comparison.
  ASSERT_EQ(post(*c, s + "/panels", {{"methods", "a2,a5"}}).status, 200);
  const Answer given = post(*c, s + "/push", {{"body", "box"}, {"impulse", {0, 3, 0}}});
  ASSERT_EQ(given.status, 200) << given.text;
  ASSERT_EQ(post(*c, s + "/step").status, 200);
  const json st = waitStats(*c, id, [](const json& j) { return j["panels"].size() == 2 && j["panels"][1]["steps"] == 1; });
  ASSERT_EQ(st["panels"].size(), 2u);
  for (int p = 0; p < 2; ++p) EXPECT_GT(st["panels"][p]["kinetic"].get<double>(), 1.0) << p;
}

TEST(Server, StreamsFramesAndStats) {
  ServerProcess srv(small());
  auto c = srv.client();
  const std::string id = create(*c, {{"scene", "stack"}, {"play", true}});
  const std::string s = "/api/sessions/" + id;
  auto streamClient = srv.client();
  int status = 0;
  const std::string mjpeg = readStream(*streamClient, s + "/stream.mjpeg", 20,
                                       [](const std::string& got) { return jpegParts(got).size() >= 4; }, &status);
  const std::vector<std::string> parts = jpegParts(mjpeg);
  ASSERT_GE(parts.size(), 4u) << mjpeg.substr(0, 200);
  EXPECT_EQ(mjpeg.rfind("--substepframe\r\n", 0), 0u);
  const auto first = substep::render::decodeImage(parts.front().data(), parts.front().size());
  const auto last = substep::render::decodeImage(parts.back().data(), parts.back().size());
  EXPECT_EQ(first.width, 320);
  EXPECT_EQ(first.height, 180);
  EXPECT_NE(first.rgba, last.rgba);  // the time in the HUD at least

  auto eventsClient = srv.client();
  const std::string events = readStream(*eventsClient, s + "/events", 20,
                                        [](const std::string& got) { return count(got, "event: stats") >= 3; });
  ASSERT_GE(count(events, "event: stats"), 3) << events.substr(0, 300);
  const size_t d = events.find("data: ");
  const json st = json::parse(events.substr(d + 6, events.find('\n', d) - d - 6));
  for (const char* k : {"fps", "physics_ms", "draw_ms", "encode_ms", "playing", "achieved", "behind"})
    EXPECT_TRUE(st.contains(k)) << k;
  for (const char* k : {"time", "step_ms", "s1_ms", "s2_ms", "s3_ms", "s4_ms", "contacts", "penetration",
                        "joint_error", "kinetic", "potential"})
    EXPECT_TRUE(st["panels"][0].contains(k)) << k;

  // Frames of the last seconds and of the next make clips.
  readStream(*streamClient, s + "/stream.mjpeg", 1.5, [](const std::string&) { return false; });
  Answer clip = post(*c, s + "/clips", {{"mode", "last"}, {"seconds", 1}});
  ASSERT_EQ(clip.status, 202) << clip.text;
  const int lastId = clip.body["id"];
  clip = post(*c, s + "/clips", {{"mode", "next"}, {"seconds", 0.5}});
  ASSERT_EQ(clip.status, 202) << clip.text;
  EXPECT_EQ(clip.body["state"], "recording");
  const int nextId = clip.body["id"];
  for (int clipId : {lastId, nextId}) {
    json info;
    for (int i = 0; i < 600; ++i) {
      info = call(*c, "GET", s + "/clips/" + std::to_string(clipId)).body;
      if (info["state"] == "done" || info["state"] == "failed") break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    ASSERT_EQ(info["state"], "done") << info.dump();
    EXPECT_GE(info["frames"].get<int>(), clipId == nextId ? 10 : 5);
    const Answer mp4 = call(*c, "GET", info["url"]);
    ASSERT_EQ(mp4.status, 200);
    EXPECT_EQ(mp4.contentType, "video/mp4");
    EXPECT_EQ(mp4.text.substr(4, 4), "ftyp");
  }
  EXPECT_EQ(call(*c, "GET", s + "/clips").body["clips"].size(), 2u);
}

TEST(Server, SessionCapAndExpiry) {
  ServerProcess srv(small({"--max-sessions", "2", "--idle-timeout", "1.5"}));
  auto c = srv.client();
  const std::string a = create(*c, {{"scene", "stack"}});
  const std::string b = create(*c, {{"scene", "stack"}});
  const Answer full = post(*c, "/api/sessions", {{"scene", "stack"}});
  EXPECT_EQ(full.status, 503);
  EXPECT_NE(full.body.value("error", "").find("limit of 2 sessions (--max-sessions)"), std::string::npos) << full.text;
  ASSERT_EQ(call(*c, "DELETE", "/api/sessions/" + a).status, 200);
  const std::string d = create(*c, {{"scene", "stack"}});
  EXPECT_FALSE(d.empty());

  // A watched session stays; one left alone expires.
  auto streamClient = srv.client();
  std::thread watch([&] { readStream(*streamClient, "/api/sessions/" + d + "/stream.mjpeg", 4, [](const std::string&) { return false; }); });
  std::this_thread::sleep_for(std::chrono::milliseconds(3000));
  EXPECT_EQ(call(*c, "GET", "/api/sessions/" + b).status, 404);
  EXPECT_EQ(call(*c, "GET", "/api/sessions/" + d).status, 200);
  watch.join();
  EXPECT_NE(srv.output().find("session " + b + " closed (idle"), std::string::npos) << srv.output();
}

TEST(Server, DivergingSessionPausesOthersGoOn) {
  ServerProcess srv(small());
  auto c = srv.client();
  const std::string bad = create(*c, {{"scene", "box_on_ground"}, {"play", true}});
  const std::string good = create(*c, {{"scene", "stack"}, {"play", true}});
  // 1e9 N s on a 1 kg box: beyond the divergence guard's speed at the next step.
  ASSERT_EQ(post(*c, "/api/sessions/" + bad + "/push", {{"body", "box"}, {"impulse", {1e9, 0, 0}}}).status, 200);
  const json st = waitStats(*c, bad, [](const json& j) { return j["panels"][0]["diverged"].get<bool>(); });
  ASSERT_TRUE(st["panels"][0]["diverged"].get<bool>()) << st.dump();
  EXPECT_NE(st["status"].get<std::string>().find("diverged"), std::string::npos) << st.dump();
  EXPECT_FALSE(waitStats(*c, bad, [](const json& j) { return !j["playing"].get<bool>(); })["playing"].get<bool>());
  // The other session plays on, and the diverged one still answers and draws its last good state.
  const double t0 = simTime(stats(*c, good));
  EXPECT_GT(simTime(waitStats(*c, good, [&](const json& j) { return simTime(j) > t0 + 0.3; })), t0 + 0.3);
  EXPECT_EQ(call(*c, "GET", "/api/sessions/" + bad + "/frame.png").status, 200);
  const Answer reset = post(*c, "/api/sessions/" + bad + "/reset");
  EXPECT_EQ(reset.body["status"], "");
  EXPECT_EQ(reset.body["panels"][0]["diverged"], false);
}

TEST(Server, InterruptStopsWithStreamsOpen) {
  ServerProcess srv(small());
  auto c = srv.client();
  const std::string id = create(*c, {{"scene", "stack"}, {"play", true}});
  auto streamClient = srv.client();
  std::thread watch([&] { readStream(*streamClient, "/api/sessions/" + id + "/stream.mjpeg", 30, [](const std::string&) { return false; }); });
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(srv.interrupt(), 130);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 10);
  watch.join();
  EXPECT_NE(srv.output().find("substep serve: stopped"), std::string::npos) << srv.output();
}

TEST(Server, CommandLine) {
  const Outcome help = runSubstep("serve --help");
  EXPECT_EQ(help.status, 0);
  for (const char* o : {"--host", "--port", "--max-sessions", "--size", "--fps", "--idle-timeout", "ssh -L"})
    EXPECT_NE(help.output.find(o), std::string::npos) << o;
  EXPECT_EQ(runSubstep("serve --size 10x10").status, 2);
  EXPECT_EQ(runSubstep("serve --port 70000").status, 2);
  EXPECT_EQ(runSubstep("serve --max-sessions 0").status, 2);
  const Outcome web = runSubstep("serve --port 0 --web /nonexistent");
  EXPECT_EQ(web.status, 2);
  EXPECT_NE(web.output.find("--web /nonexistent: no index.html"), std::string::npos) << web.output;
  // A port in use is a clear failure, not a hang.
  ServerProcess srv(small());
  const Outcome busy = runSubstep("serve --port " + std::to_string(srv.port()));
  EXPECT_EQ(busy.status, 1);
  EXPECT_NE(busy.output.find("cannot listen on 127.0.0.1:" + std::to_string(srv.port())), std::string::npos) << busy.output;
}

// The timeline: kept steps shown at once (no stepping again), step back, play backwards, live; the
// past refuses a push; markers; the inspector of a selected body and "jump to worst".
TEST(Server, TimelineScrubSelectInspectAndWorst) {
  ServerProcess srv(small());
  auto c = srv.client();
  const std::string id = create(*c, {{"scene", "pile"}, {"methods", "a2,a5"}});
  const std::string s = "/api/sessions/" + id;
  ASSERT_EQ(post(*c, s + "/step", {{"count", 90}}).status, 200);
  Answer tl = call(*c, "GET", s + "/timeline");
  ASSERT_EQ(tl.status, 200) << tl.text;
  EXPECT_EQ(tl.body["first"], 0);
  EXPECT_NEAR(tl.body["last"].get<double>(), 1.5, 1e-9);
  EXPECT_EQ(tl.body["live"], true);
  EXPECT_EQ(tl.body["kept"], 91);
  bool penetration = false;
  for (const json& m : tl.body["markers"]) penetration = penetration || m["kind"] == "penetration";
  EXPECT_TRUE(penetration) << tl.text;

  // Body "col_0_0_9" at the newest step, then at step 30.
  const Answer selected = post(*c, s + "/select", {{"body", "col_0_0_9"}});
  ASSERT_EQ(selected.status, 200) << selected.text;
  ASSERT_EQ(selected.body["panels"].size(), 2u);
  const json liveBox = selected.body["panels"][0];
  EXPECT_EQ(liveBox["step"], 90);
  Answer scrubbed = post(*c, s + "/scrub", {{"time", 0.5}});
  ASSERT_EQ(scrubbed.status, 200) << scrubbed.text;
  EXPECT_EQ(scrubbed.body["timeline"]["live"], false);
  EXPECT_EQ(scrubbed.body["timeline"]["shown_step"], 30);
  EXPECT_EQ(scrubbed.body["selected"], "col_0_0_9");
  const json st = stats(*c, id);
  EXPECT_EQ(st["panels"][0]["steps"], 90);  // nothing stepped again
  EXPECT_EQ(st["shown_step"], 30);
  const Answer past = call(*c, "GET", s + "/inspect");
  ASSERT_EQ(past.status, 200) << past.text;
  EXPECT_EQ(past.body["body"], "col_0_0_9");
  EXPECT_EQ(past.body["panels"][0]["step"], 30);
  EXPECT_NE(past.body["panels"][0]["position"], liveBox["position"]);  // it was falling then
  EXPECT_EQ(post(*c, s + "/scrub", {{"step", 42}}).body["timeline"]["shown_step"], 42);
  EXPECT_EQ(post(*c, s + "/scrub", {{"step", 500}}).status, 409);
  ASSERT_EQ(post(*c, s + "/scrub", {{"step", 30}}).status, 200);
  EXPECT_EQ(post(*c, s + "/scrub", {{"by", -5}}).body["timeline"]["shown_step"], 25);
  EXPECT_EQ(post(*c, s + "/step", {{"count", -2}}).body["timeline"]["shown_step"], 23);
  EXPECT_EQ(post(*c, s + "/step", {{"count", 3}}).body["timeline"]["shown_step"], 26);  // forward through the kept steps
  EXPECT_EQ(stats(*c, id)["panels"][0]["steps"], 90);

  // The past cannot be pushed: 409, saying how to go on.
  const Answer push = post(*c, s + "/push", {{"body", "col_0_0_9"}, {"impulse", {0, 3, 0}}});
  EXPECT_EQ(push.status, 409) << push.text;
  EXPECT_NE(push.text.find("go live first"), std::string::npos) << push.text;

  // Backwards to the first kept step, where it pauses.
  ASSERT_EQ(post(*c, s + "/play", {{"speed", -2}}).status, 200);
  const json back = waitStats(*c, id, [](const json& j) { return !j["playing"].get<bool>(); });
  EXPECT_EQ(back["shown_step"], 0);
  EXPECT_NE(back["status"].get<std::string>().find("first kept step"), std::string::npos) << back.dump();

  // The worst penetration so far: shown at its step, its body selected.
  const Answer worst = post(*c, s + "/worst", {{"kind", "penetration"}});
  ASSERT_EQ(worst.status, 200) << worst.text;
  const json& m = worst.body["marker"];
  EXPECT_EQ(m["kind"], "penetration");
  ASSERT_TRUE(m["body"].is_string()) << worst.text;
  EXPECT_EQ(worst.body["inspect"]["body"], m["body"]);
  const Answer after = call(*c, "GET", s);
  EXPECT_DOUBLE_EQ(after.body["timeline"]["shown"].get<double>(), m["time"].get<double>());
  EXPECT_EQ(after.body["selected"], m["body"]);
  double deepest = 0;
  for (const json& k : worst.body["inspect"]["panels"][m["panel"].get<int>()]["contacts"])
    deepest = std::max(deepest, k["depth"].get<double>());
  EXPECT_DOUBLE_EQ(deepest, m["value"].get<double>());  // the marker's number is the inspector's
  EXPECT_EQ(post(*c, s + "/worst", {{"kind", "nope"}}).status, 400);

  // Live again: the newest step, and a push works.
  EXPECT_EQ(post(*c, s + "/scrub", {{"live", true}}).body["timeline"]["shown_step"], 90);
  EXPECT_EQ(post(*c, s + "/push", {{"body", "col_0_0_9"}, {"impulse", {0, 3, 0}}}).status, 200);
  EXPECT_EQ(post(*c, s + "/scrub", json::object()).status, 400);
  EXPECT_EQ(post(*c, s + "/select", {{"body", "nobody"}}).status, 400);
  EXPECT_EQ(post(*c, s + "/select", {{"body", nullptr}}).body["body"], nullptr);
}

// A recording replayed: offered by --open, opened as a session that never steps, its inspector's
// numbers the recording's own to the last bit; uploads; damaged recordings refused with the reason.
TEST(Server, RecordingsReplayAsRecorded) {
  const fs::path dir = scratchFolder("server");
  fs::create_directories(dir);
  const std::string rec = (dir / "ragdoll.rec").string();
  ASSERT_EQ(runSubstep("run assets/scenes/ragdoll.json --seconds 1 -q --record " + rec).status, 0);
  const substep::Recording file = substep::readRecording(rec);
  std::ifstream in(rec, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  const std::string cut = (dir / "cut.rec").string();
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() - 100);

  // A damaged --open stops the server before it starts.
  const Outcome bad = runSubstep("serve --port 0 --open " + cut);
  EXPECT_EQ(bad.status, 2) << bad.output;
  EXPECT_NE(bad.output.find(cut + ": truncated at byte"), std::string::npos) << bad.output;

  ServerProcess srv(small({"--open", rec}));
  auto c = srv.client();
  EXPECT_EQ(call(*c, "GET", "/api/server").body["open"], json::array({"ragdoll.rec"}));
  bool listed = false;
  const json recordings = call(*c, "GET", "/api/recordings").body["recordings"];
  for (const json& r : recordings) listed = listed || r["name"] == "ragdoll.rec";
  EXPECT_TRUE(listed) << recordings;
  Answer opened = post(*c, "/api/sessions", {{"recording", "ragdoll.rec"}});
  ASSERT_EQ(opened.status, 201) << opened.text;
  const std::string sid = opened.body["id"].get<std::string>(), s = "/api/sessions/" + sid;
  EXPECT_EQ(opened.body["timeline"]["recorded"], true);
  EXPECT_EQ(opened.body["timeline"]["kept"], 61);
  EXPECT_EQ(opened.body["timeline"]["shown_step"], 0);
  ASSERT_EQ(post(*c, s + "/step", {{"count", 25}}).body["timeline"]["shown_step"], 25);
  const std::string body = "ragdoll_0_head";
  const Answer ins = post(*c, s + "/select", {{"body", body}});
  ASSERT_EQ(ins.status, 200) << ins.text;
  const json& p = ins.body["panels"][0];
  const size_t b = static_cast<size_t>(substep::recordingScene(file).model.bodyIndex(body));
  const substep::BodyState& want = file.panels[0][25].state.bodies[b];
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(p["position"][k].get<double>(), want.x[k]);  // bit for bit through the JSON
    EXPECT_EQ(p["velocity"][k].get<double>(), want.v[k]);
  }
  EXPECT_EQ(p["orientation"][0].get<double>(), want.q.w());
  // Playing runs to the recording's end and stops there; nothing is pushed into a recording.
  ASSERT_EQ(post(*c, s + "/play", {{"speed", 10}}).status, 200);
  const json end = waitStats(*c, sid, [](const json& j) { return !j["playing"].get<bool>(); });
  EXPECT_EQ(end["shown_step"], 60);
  EXPECT_NE(end["status"].get<std::string>().find("end of the recording"), std::string::npos) << end.dump();
  EXPECT_EQ(end["panels"][0]["steps"], 0);  // replayed, never stepped
  EXPECT_EQ(post(*c, s + "/push", {{"body", body}, {"impulse", {0, 1, 0}}}).status, 409);
  EXPECT_EQ(post(*c, s + "/settings", {{"settings", {{"n", 8}}}}).status, 409);

  // Uploads: a damaged one is refused with its reason; a whole one opens.
  httplib::Result up = c->Post("/api/recordings?name=cut.rec", bytes.substr(0, bytes.size() - 100), "application/octet-stream");
  ASSERT_TRUE(up);
  EXPECT_EQ(up->status, 400);
  EXPECT_NE(up->body.find("truncated at byte"), std::string::npos) << up->body;
  up = c->Post("/api/recordings?name=mine.rec", bytes, "application/octet-stream");
  ASSERT_TRUE(up);
  ASSERT_EQ(up->status, 201) << up->body;
  const std::string name = json::parse(up->body)["name"];
  EXPECT_EQ(post(*c, "/api/sessions", {{"recordings", {"ragdoll.rec", name}}}).body["panels"].size(), 2u);
  EXPECT_EQ(post(*c, "/api/sessions", {{"recording", "nope.rec"}}).status, 400);
  EXPECT_EQ(post(*c, "/api/sessions", {{"recording", "../../etc/passwd"}}).status, 400);
  EXPECT_EQ(post(*c, "/api/sessions", {{"recording", "ragdoll.rec"}, {"scene", "stack"}}).status, 400);
}

// From the atlas into the viewer: `atlas --record` inside the lab folder, `serve --lab`: each cell
// links its scene's recordings, and the session they open shows the cell's panel at its first
// failure with the deciding body selected.
TEST(Server, AtlasCellsOpenAtTheirFirstFailure) {
  const fs::path dir = emptyScratchFolder("server");
  const std::string atlas = (dir / "lab" / "atlas").string();
  const Outcome made = runSubstep("atlas --scenes mass_ratio_box_100 --methods a2,a5 --no-clips -q -o " + atlas +
                                  " --record " + atlas + "/recordings");
  ASSERT_EQ(made.status, 0) << made.output;
  ServerProcess srv(small({"--lab", (dir / "lab").string()}));
  auto c = srv.client();
  const Answer page = call(*c, "GET", "/lab/atlas/index.html");
  ASSERT_EQ(page.status, 200);
  const std::string link = "data-recordings=\"recordings/mass_ratio_box_100-a2.rec,recordings/mass_ratio_box_100-a5.rec\" data-panel=\"1\"";
  EXPECT_NE(page.text.find(link), std::string::npos) << page.text.substr(0, 2000);
  const Answer opened = post(*c, "/api/sessions", {{"recordings", "atlas/recordings/mass_ratio_box_100-a2.rec,atlas/recordings/mass_ratio_box_100-a5.rec"},
                                                   {"focus", 1}});
  ASSERT_EQ(opened.status, 201) << opened.text;
  const std::string s = "/api/sessions/" + opened.body["id"].get<std::string>();
  json first;
  const json markers = call(*c, "GET", s + "/timeline").body["markers"];
  for (const json& m : markers)
    if (m["panel"] == 1 && m["kind"] == "criterion" && first.is_null()) first = m;
  ASSERT_FALSE(first.is_null()) << "a5 fails this scene (tests/data/atlas_expected.json): a criterion marker; " << markers;
  EXPECT_DOUBLE_EQ(opened.body["timeline"]["shown"].get<double>(), first["time"].get<double>());
  EXPECT_GT(first["time"].get<double>(), 0);
  EXPECT_EQ(opened.body["selected"], first["body"]);
  EXPECT_EQ(opened.body["panels"].size(), 2u);
}
