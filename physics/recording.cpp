#include "physics/recording.h"

#include "physics/limits.h"

#include <unistd.h>
#include <xxhash.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

namespace substep {

namespace {

using json = nlohmann::json;

constexpr size_t kMagicBytes = sizeof kRecordingMagic - 1;
constexpr size_t kHeaderBytes = kMagicBytes + 4;                  // magic, version
constexpr size_t kFooterBytes = 1 + 8 + 8 + kMagicBytes;          // tag, frames, checksum, end mark
constexpr size_t kFrameFixedBytes = 1 + 4 + 8 + 8 + 5 * 4;        // tag, panel, step, time, five counts
constexpr size_t kBodyBytes = 13 * 8;
constexpr size_t kManifoldBytes = 4 * 4 + 4 * 4;
constexpr size_t kContactBytes = 8 * 4;
constexpr size_t kJointBytes = 7 * 4;
constexpr size_t kMaxPanels = 1024;
static_assert(sizeof(double) == 8 && sizeof(float) == 4 && std::numeric_limits<double>::is_iec559);

// --- little-endian encoding -----------------------------------------------------------------------

void putU8(std::string& b, uint8_t v) { b.push_back(static_cast<char>(v)); }
void putU32(std::string& b, uint32_t v) {
  for (int i = 0; i < 4; ++i) b.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
}
void putU64(std::string& b, uint64_t v) {
  for (int i = 0; i < 8; ++i) b.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
}
void putI32(std::string& b, int32_t v) { putU32(b, static_cast<uint32_t>(v)); }
void putF64(std::string& b, double v) {
  uint64_t u;
  std::memcpy(&u, &v, 8);
  putU64(b, u);
}
void putF32(std::string& b, float v) {
  uint32_t u;
  std::memcpy(&u, &v, 4);
  putU32(b, u);
}
void putVec3(std::string& b, const Vec3& v) {
  for (int i = 0; i < 3; ++i) putF64(b, v[i]);
}
void putVec3f(std::string& b, const Vec3f32& v) {
  for (int i = 0; i < 3; ++i) putF32(b, v[i]);
}

uint32_t getU32(const unsigned char* p) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<uint32_t>(p[i]) << (8 * i);
  return v;
}
uint64_t getU64(const unsigned char* p) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<uint64_t>(p[i]) << (8 * i);
  return v;
}
double getF64(const unsigned char* p) {
  const uint64_t u = getU64(p);
  double v;
  std::memcpy(&v, &u, 8);
  return v;
}
float getF32(const unsigned char* p) {
  const uint32_t u = getU32(p);
  float v;
  std::memcpy(&v, &u, 4);
  return v;
}

// A count in the metadata: an integer in [0, hi].
std::optional<size_t> metaCount(const json& meta, const char* key, size_t hi) {
  const auto it = meta.find(key);
  if (it == meta.end() || !it->is_number_integer()) return std::nullopt;
  const long long v = it->get<long long>();
  if (v < 0 || static_cast<unsigned long long>(v) > hi) return std::nullopt;
  return static_cast<size_t>(v);
}

bool bodyFinite(const BodyState& b) {
  return b.x.allFinite() && b.q.coeffs().allFinite() && b.v.allFinite() && b.w.allFinite();
}

// What the writer checks of the metadata and the reader of a parsed one; "" when it fits.
std::string metaProblem(const json& meta, size_t& bodies, size_t& joints, size_t& panels) {
  if (!meta.is_object()) return "expected a JSON object";
  const auto b = metaCount(meta, "bodies", limits::kMaxBodiesCeiling);
  if (!b) return "\"bodies\": expected the model's body count, an integer in [0, " + std::to_string(limits::kMaxBodiesCeiling) + "]";
  const auto j = metaCount(meta, "joints", limits::kMaxBodiesCeiling);
  if (!j) return "\"joints\": expected the model's joint count, an integer in [0, " + std::to_string(limits::kMaxBodiesCeiling) + "]";
  const auto p = meta.find("panels");
  if (p == meta.end() || !p->is_array() || p->empty() || p->size() > kMaxPanels)
    return "\"panels\": expected an array of 1 to " + std::to_string(kMaxPanels) + " panels";
  bodies = *b;
  joints = *j;
  panels = p->size();
  return "";
}

// --- reading ----------------------------------------------------------------------------------

using Problem = RecordingError::Problem;

class Parser {
 public:
  Parser(const std::string& bytes, const std::string& name)
      : p_(reinterpret_cast<const unsigned char*>(bytes.data())), size_(bytes.size()), name_(name) {}

  Recording parse() {
    header();
    Recording r;
    r.file = name_;
    r.meta = metadata();
    r.panels.resize(panels_);
    std::vector<long long> lastStep(panels_, -1);
    long long frames = 0;
    while (true) {
      if (pos_ == size_)
        fail(Problem::Truncated, "truncated at byte " + std::to_string(pos_) +
                                     (frames ? " (after frame " + std::to_string(frames - 1) + ")" : std::string(" (before any frame)")) +
                                     ": the footer is missing, the recording was not finished");
      frame_ = frames;
      const uint8_t tag = p_[pos_];
      if (tag == kFooterTag) {
        footer(frames);
        return r;
      }
      if (tag != kFrameTag)
        fail(sealed_ ? Problem::Malformed : Problem::Corrupt,
             "corrupt: an unknown tag " + std::to_string(tag) + " at byte " + std::to_string(pos_) + " (frame " +
                 std::to_string(frames) + ")");
      Snapshot s;
      const uint32_t panel = frame(s);
      if (s.state.step <= lastStep[panel])
        fail(Problem::Malformed, "frame " + std::to_string(frames) + ": step " + std::to_string(s.state.step) + " of panel " +
                                     std::to_string(panel) + " does not come after step " + std::to_string(lastStep[panel]));
      lastStep[panel] = s.state.step;
      r.panels[panel].push_back(std::move(s));
      ++frames;
    }
  }

 private:
  [[noreturn]] void fail(Problem p, const std::string& what) const { throw RecordingError(p, name_ + ": " + what); }

  // n more bytes, or the file ends: truncated (or, in a sealed file, a size beyond the file).
  // A sealed file's frames end where its footer starts.
  void need(size_t n, const std::string& where, bool footer = false) const {
    const size_t end = sealed_ && !footer ? size_ - kFooterBytes : size_;
    if (pos_ <= end && n <= end - pos_) return;
    if (sealed_)
      fail(Problem::TooLarge, "too large: " + where + " needs " + std::to_string(n) + " bytes at byte " + std::to_string(pos_) +
                                  ", beyond the file's " + std::to_string(size_));
    fail(Problem::Truncated, "truncated at byte " + std::to_string(size_) + " (in " + where + ")");
  }
  std::string inFrame() const { return "frame " + std::to_string(frame_); }

  uint32_t u32() {
    const uint32_t v = getU32(p_ + pos_);
    pos_ += 4;
    return v;
  }
  uint64_t u64() {
    const uint64_t v = getU64(p_ + pos_);
    pos_ += 8;
    return v;
  }
  double f64() {
    const double v = getF64(p_ + pos_);
    pos_ += 8;
    return v;
  }
  float f32() {
    const float v = getF32(p_ + pos_);
    pos_ += 4;
    return v;
  }
  Vec3 vec3() {
    Vec3 v;
    for (int i = 0; i < 3; ++i) v[i] = f64();
    return v;
  }
  Vec3f32 vec3f() {
    Vec3f32 v;
    for (int i = 0; i < 3; ++i) v[i] = f32();
    return v;
  }

  void header() {
    if (size_ == 0) fail(Problem::NotRecording, "not a recording: the file is empty");
    const size_t m = std::min(size_, kMagicBytes);
    if (std::memcmp(p_, kRecordingMagic, m) != 0) fail(Problem::NotRecording, "not a recording (it does not start with SUBSTEPREC)");
    if (size_ < kHeaderBytes) fail(Problem::Truncated, "truncated at byte " + std::to_string(size_) + " (in the header)");
    pos_ = kMagicBytes;
    version_ = u32();
    if (version_ < kRecordingOldestVersion || version_ > kRecordingVersion)
      fail(Problem::Version, "unknown version " + std::to_string(version_) + " (this build reads versions " +
                                 std::to_string(kRecordingOldestVersion) + " to " + std::to_string(kRecordingVersion) + ")");
    // Sealed: it ends with the end mark, so the checksum before it is checked first, and a flipped
    // byte anywhere is reported as such rather than as whatever it happens to break.
    if (size_ >= kHeaderBytes + 4 + kFooterBytes &&
        std::memcmp(p_ + size_ - kMagicBytes, kRecordingEndMark, kMagicBytes) == 0) {
      checksum(size_ - kFooterBytes);
      sealed_ = true;
    }
  }

  // The footer at `at`: XXH3-64 of every byte before its checksum.
  void checksum(size_t at) const {
    const uint64_t stored = getU64(p_ + at + 9);
    const uint64_t computed = XXH3_64bits(p_, at + 9);
    if (stored != computed) {
      char buf[96];
      std::snprintf(buf, sizeof buf, "stored %016llx, computed %016llx", static_cast<unsigned long long>(stored),
                    static_cast<unsigned long long>(computed));
      fail(Problem::Corrupt, std::string("checksum mismatch: the file is corrupt (") + buf + ")");
    }
  }

  json metadata() {
    need(4, "the metadata's length");
    const uint32_t n = u32();
    need(n, "the metadata");
    const char* text = reinterpret_cast<const char*>(p_ + pos_);
    json meta = json::parse(text, text + n, nullptr, false);
    pos_ += n;
    if (meta.is_discarded()) fail(Problem::Malformed, "malformed: the metadata is not JSON");
    const std::string why = metaProblem(meta, bodies_, joints_, panels_);
    if (!why.empty()) fail(Problem::Malformed, "malformed metadata: " + why);
    return meta;
  }

  // A count of items of `each` bytes: at most `limit` when one is given, and within the file.
  size_t count(const char* what, size_t each) {
    need(4, inFrame() + "'s " + what + " count");
    const uint32_t n = u32();
    need(static_cast<size_t>(n) * each, inFrame() + "'s " + std::to_string(n) + " " + what);
    return n;
  }

  uint32_t frame(Snapshot& s) {
    need(1 + 4 + 8 + 8, inFrame());
    ++pos_;  // the tag
    const uint32_t panel = u32();
    if (panel >= panels_)
      fail(Problem::Malformed, inFrame() + ": panel " + std::to_string(panel) + ", but the metadata has " +
                                   std::to_string(panels_) + " panels");
    const uint64_t step = u64();
    if (step > static_cast<uint64_t>(std::numeric_limits<long long>::max()))
      fail(Problem::Malformed, inFrame() + ": a negative step");
    s.state.step = static_cast<long long>(step);
    s.state.time = f64();
    if (!std::isfinite(s.state.time)) fail(Problem::Malformed, inFrame() + ": the time is not finite");

    need(4, inFrame() + "'s body count");
    const uint32_t bodies = u32();
    if (bodies != bodies_)
      fail(Problem::TooLarge, "too large: " + inFrame() + " has " + std::to_string(bodies) + " bodies; the metadata says " +
                                  std::to_string(bodies_));
    need(static_cast<size_t>(bodies) * kBodyBytes, inFrame() + "'s bodies");
    s.state.bodies.resize(bodies);
    for (uint32_t i = 0; i < bodies; ++i) {
      BodyState& b = s.state.bodies[i];
      b.x = vec3();
      const double w = f64(), x = f64(), y = f64(), z = f64();
      b.q = Quat(w, x, y, z);
      b.v = vec3();
      b.w = vec3();
      if (!bodyFinite(b)) fail(Problem::Malformed, inFrame() + ": body " + std::to_string(i) + " has a non-finite value");
    }

    const size_t manifolds = count("manifolds", kManifoldBytes);
    s.manifolds.resize(manifolds);
    for (ManifoldSnap& m : s.manifolds) {
      m.a = static_cast<int32_t>(u32());
      m.b = static_cast<int32_t>(u32());
      m.first = static_cast<int32_t>(u32());
      m.count = static_cast<int32_t>(u32());
      m.friction = vec3f();
      m.twist = f32();
    }
    const size_t contacts = count("contacts", kContactBytes);
    s.contacts.resize(contacts);
    for (ContactSnap& c : s.contacts) {
      c.point = vec3f();
      c.normal = vec3f();
      c.depth = f32();
      c.normalImpulse = f32();
    }
    for (size_t k = 0; k < manifolds; ++k) {
      const ManifoldSnap& m = s.manifolds[k];
      if (m.a < 0 || m.b < 0 || static_cast<size_t>(m.a) >= bodies_ || static_cast<size_t>(m.b) >= bodies_ || m.first < 0 ||
          m.count < 0 || static_cast<int64_t>(m.first) + m.count > static_cast<int64_t>(contacts))
        fail(Problem::Malformed, inFrame() + ": manifold " + std::to_string(k) + " names bodies or contacts it does not have");
    }
    need(4, inFrame() + "'s joint count");
    const uint32_t joints = u32();
    if (joints != joints_)
      fail(Problem::TooLarge, "too large: " + inFrame() + " has " + std::to_string(joints) + " joints; the metadata says " +
                                  std::to_string(joints_));
    need(static_cast<size_t>(joints) * kJointBytes, inFrame() + "'s joints");
    s.joints.resize(joints);
    for (JointSnap& j : s.joints) {
      j.error = f32();
      j.linear = vec3f();
      j.angular = vec3f();
    }
    if (version_ >= 2) {
      const size_t asleep = count("asleep bodies", 4);
      s.asleep.resize(asleep);
      for (size_t k = 0; k < asleep; ++k) {
        const uint32_t i = u32();
        if (i >= bodies_ || (k > 0 && i <= static_cast<uint32_t>(s.asleep[k - 1])))
          fail(Problem::Malformed, inFrame() + ": asleep body " + std::to_string(i) + " is not a body, or not in increasing order");
        s.asleep[k] = static_cast<int32_t>(i);
      }
    }
    return panel;
  }

  void footer(long long frames) {
    need(kFooterBytes, "the footer", true);
    const size_t at = pos_;
    pos_ += 1;
    const uint64_t stored = u64();
    pos_ += 8;  // the checksum
    if (std::memcmp(p_ + pos_, kRecordingEndMark, kMagicBytes) != 0) fail(Problem::Corrupt, "corrupt: the end mark is damaged");
    pos_ += kMagicBytes;
    if (!sealed_) checksum(at);
    if (pos_ != size_)
      fail(Problem::Corrupt, "corrupt: " + std::to_string(size_ - pos_) + " bytes after the end of the recording");
    if (stored != static_cast<uint64_t>(frames))
      fail(Problem::Malformed, "malformed: the footer counts " + std::to_string(stored) + " frames, the file holds " +
                                   std::to_string(frames));
  }

  const unsigned char* p_;
  size_t size_, pos_ = 0;
  std::string name_;
  bool sealed_ = false;
  size_t bodies_ = 0, joints_ = 0, panels_ = 0;
  uint32_t version_ = kRecordingVersion;
  long long frame_ = 0;
};

}  // namespace

const char* problemName(RecordingError::Problem p) {
  switch (p) {
    case Problem::Unreadable: return "unreadable";
    case Problem::NotRecording: return "not a recording";
    case Problem::Version: return "unknown version";
    case Problem::Truncated: return "truncated";
    case Problem::Corrupt: return "corrupt";
    case Problem::TooLarge: return "too large";
    case Problem::Malformed: return "malformed";
  }
  return "?";
}

long long Recording::frames() const {
  long long n = 0;
  for (const auto& p : panels) n += static_cast<long long>(p.size());
  return n;
}

Recording parseRecording(const std::string& bytes, const std::string& name) { return Parser(bytes, name).parse(); }

Recording readRecording(const std::string& path, size_t maxBytes) {
  // Not readInputFile: its message would be a scene's, and the size limit is this reader's.
  std::ifstream in(path, std::ios::binary);
  if (!in) throw RecordingError(Problem::Unreadable, path + ": cannot open: " + std::strerror(errno));
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size < 0) throw RecordingError(Problem::Unreadable, path + ": cannot read (not a regular file?)");
  if (static_cast<unsigned long long>(size) > maxBytes)
    throw RecordingError(Problem::TooLarge, path + ": too large: " + std::to_string(size) + " bytes, more than the " +
                                                std::to_string(maxBytes) + " bytes this reader takes");
  in.seekg(0);
  std::string bytes(static_cast<size_t>(size), '\0');
  if (size > 0 && !in.read(bytes.data(), size))
    throw RecordingError(Problem::Unreadable, path + ": cannot read: " + std::strerror(errno));
  return parseRecording(bytes, path);
}

Scene recordingScene(const Recording& r, const SceneLimits& lim) {
  auto bad = [&](const std::string& what) { return RecordingError(Problem::Malformed, r.file + ": " + what); };
  const json* scene = r.meta.is_object() && r.meta.contains("scene") ? &r.meta["scene"] : nullptr;
  if (!scene || !scene->is_object() || !scene->contains("text") || !(*scene)["text"].is_string())
    throw bad("the metadata has no scene (scene.text)");
  const std::string file = scene->contains("file") && (*scene)["file"].is_string() ? (*scene)["file"].get<std::string>() : r.file;
  const std::string dir =
      scene->contains("base_dir") && (*scene)["base_dir"].is_string() ? (*scene)["base_dir"].get<std::string>() : ".";
  Scene s;
  try {
    s = parseScene((*scene)["text"].get<std::string>(), file, dir, lim);
  } catch (const SceneError& e) {
    throw bad(std::string("its scene: ") + e.what());
  }
  if (s.model.bodies.size() != r.meta.value("bodies", size_t(0)))
    throw bad("its scene has " + std::to_string(s.model.bodies.size()) + " bodies, its frames " +
              std::to_string(r.meta.value("bodies", size_t(0))));
  return s;
}

// --- writing ----------------------------------------------------------------------------------

RecordingWriter::RecordingWriter(const std::string& path, const json& meta) : path_(path) {
  if (const std::string why = metaProblem(meta, bodies_, joints_, panels_); !why.empty())
    throw std::invalid_argument("recording metadata: " + why);
  const std::string text = meta.dump(-1, ' ', false, json::error_handler_t::replace);
  if (text.size() > std::numeric_limits<uint32_t>::max()) throw std::invalid_argument("recording metadata: beyond 4 GiB");
  temp_ = path + ".part" + std::to_string(::getpid());
  file_ = std::fopen(temp_.c_str(), "wb");
  if (!file_) throw RecordingError(Problem::Unreadable, path + ": cannot create " + temp_ + ": " + std::strerror(errno));
  std::setvbuf(file_, nullptr, _IOFBF, 1 << 20);
  hash_ = XXH3_createState();
  XXH3_64bits_reset(hash_);
  std::string h(kRecordingMagic, kMagicBytes);
  putU32(h, kRecordingVersion);
  putU32(h, static_cast<uint32_t>(text.size()));
  h += text;
  write(h);
}

RecordingWriter::~RecordingWriter() {
  if (file_) std::fclose(file_);
  if (!committed_ && !temp_.empty()) std::remove(temp_.c_str());
  if (hash_) XXH3_freeState(hash_);
}

void RecordingWriter::write(const std::string& bytes, bool hashed) {
  if (committed_) throw std::logic_error("RecordingWriter: written after commit()");
  if (hashed) XXH3_64bits_update(hash_, bytes.data(), bytes.size());
  if (std::fwrite(bytes.data(), 1, bytes.size(), file_) != bytes.size())
    throw RecordingError(Problem::Unreadable, path_ + ": cannot write " + temp_ + ": " + std::strerror(errno));
  bytes_ += bytes.size();
}

void RecordingWriter::add(int panel, const Snapshot& s) {
  const State& st = s.state;
  if (panel < 0 || static_cast<size_t>(panel) >= panels_)
    throw std::invalid_argument("recording: panel " + std::to_string(panel) + " of " + std::to_string(panels_));
  if (st.bodies.size() != bodies_ || s.joints.size() != joints_)
    throw std::invalid_argument("recording: a frame of " + std::to_string(st.bodies.size()) + " bodies and " +
                                std::to_string(s.joints.size()) + " joints, the metadata's are " + std::to_string(bodies_) +
                                " and " + std::to_string(joints_));
  if (st.step < 0 || !std::isfinite(st.time)) throw std::invalid_argument("recording: a frame of a negative step or non-finite time");
  for (const BodyState& b : st.bodies)
    if (!bodyFinite(b)) throw std::invalid_argument("recording: a frame with a non-finite body state (step " + std::to_string(st.step) + ")");
  for (const ManifoldSnap& m : s.manifolds)
    if (m.a < 0 || m.b < 0 || static_cast<size_t>(m.a) >= bodies_ || static_cast<size_t>(m.b) >= bodies_ || m.first < 0 ||
        m.count < 0 || static_cast<size_t>(m.first) + static_cast<size_t>(m.count) > s.contacts.size())
      throw std::invalid_argument("recording: a manifold naming bodies or contacts the frame does not have");
  for (size_t k = 0; k < s.asleep.size(); ++k)
    if (s.asleep[k] < 0 || static_cast<size_t>(s.asleep[k]) >= bodies_ || (k > 0 && s.asleep[k] <= s.asleep[k - 1]))
      throw std::invalid_argument("recording: asleep bodies not bodies of the frame, or not in increasing order");
  buf_.clear();
  buf_.reserve(kFrameFixedBytes + bodies_ * kBodyBytes + s.manifolds.size() * kManifoldBytes + s.contacts.size() * kContactBytes +
               joints_ * kJointBytes);
  putU8(buf_, kFrameTag);
  putU32(buf_, static_cast<uint32_t>(panel));
  putU64(buf_, static_cast<uint64_t>(st.step));
  putF64(buf_, st.time);
  putU32(buf_, static_cast<uint32_t>(st.bodies.size()));
  for (const BodyState& b : st.bodies) {
    putVec3(buf_, b.x);
    putF64(buf_, b.q.w());
    putF64(buf_, b.q.x());
    putF64(buf_, b.q.y());
    putF64(buf_, b.q.z());
    putVec3(buf_, b.v);
    putVec3(buf_, b.w);
  }
  putU32(buf_, static_cast<uint32_t>(s.manifolds.size()));
  for (const ManifoldSnap& m : s.manifolds) {
    putI32(buf_, m.a);
    putI32(buf_, m.b);
    putI32(buf_, m.first);
    putI32(buf_, m.count);
    putVec3f(buf_, m.friction);
    putF32(buf_, m.twist);
  }
  putU32(buf_, static_cast<uint32_t>(s.contacts.size()));
  for (const ContactSnap& c : s.contacts) {
    putVec3f(buf_, c.point);
    putVec3f(buf_, c.normal);
    putF32(buf_, c.depth);
    putF32(buf_, c.normalImpulse);
  }
  putU32(buf_, static_cast<uint32_t>(s.joints.size()));
  for (const JointSnap& j : s.joints) {
    putF32(buf_, j.error);
    putVec3f(buf_, j.linear);
    putVec3f(buf_, j.angular);
  }
  putU32(buf_, static_cast<uint32_t>(s.asleep.size()));
  for (const int32_t i : s.asleep) putU32(buf_, static_cast<uint32_t>(i));
  write(buf_);
  ++frames_;
}

void RecordingWriter::commit() {
  std::string f;
  putU8(f, kFooterTag);
  putU64(f, static_cast<uint64_t>(frames_));
  write(f);
  std::string tail;
  putU64(tail, XXH3_64bits_digest(hash_));
  tail.append(kRecordingEndMark, kMagicBytes);
  write(tail, false);
  const bool flushed = std::fflush(file_) == 0;
  const int closed = std::fclose(file_);
  file_ = nullptr;
  if (!flushed || closed != 0) throw RecordingError(Problem::Unreadable, path_ + ": cannot write " + temp_ + ": " + std::strerror(errno));
  if (std::rename(temp_.c_str(), path_.c_str()) != 0)
    throw RecordingError(Problem::Unreadable, path_ + ": cannot rename " + temp_ + " to it: " + std::strerror(errno));
  committed_ = true;
}

// --- the observer -----------------------------------------------------------------------------

void RecordingObserver::take(const Engine& e) {
  writer_.add(panel_, e.world() ? takeSnapshot(*e.world()) : takeSnapshot(model_, e.state()));
}

void RecordingObserver::begin(const Engine& e) { take(e); }

void RecordingObserver::observe(const Engine& e, const StepRecord& r) {
  if (r.finite && (r.step % every_ == 0 || r.step == planned_)) take(e);
}

}  // namespace substep
