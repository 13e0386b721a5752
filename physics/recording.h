// Recordings: a run's snapshots (physics/snapshot.h) in one binary file, streamed as the run
// steps, read back whole or refused with a reason. `substep run --record`, `sweep --record` and
// `atlas --record` write them; the viewer and `render` replay them. The format, byte by byte,
// and its metadata are in docs/recordings.md.
//
//   RecordingWriter w("out/x.rec", meta);   // writes out/x.rec.part<pid>
//   w.add(0, takeSnapshot(world));           // a frame, written at once
//   w.commit();                              // the footer, then renamed to out/x.rec
//
//   Recording r = readRecording("out/x.rec");  // or throws RecordingError
#pragma once

#include "physics/run.h"
#include "physics/scene_file.h"
#include "physics/snapshot.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

struct XXH3_state_s;

namespace substep {

inline constexpr char kRecordingMagic[] = "SUBSTEPREC";   // the first 10 bytes (no NUL)
inline constexpr char kRecordingEndMark[] = "SUBSTEPEND"; // the last 10 bytes
inline constexpr uint32_t kRecordingVersion = 2;    // what this build writes; it reads 1 and 2
inline constexpr uint32_t kRecordingOldestVersion = 1;  // version 1 frames have no asleep list
inline constexpr uint8_t kFrameTag = 'F';
inline constexpr uint8_t kFooterTag = 'E';
inline constexpr size_t kDefaultMaxRecordingBytes = size_t(2) << 30;  // what readRecording takes by default [bytes]

// Why a recording is refused. The message names the file and says what is wrong; problem() says
// which kind, for callers that add advice (how to raise the size limit) and for tests.
class RecordingError : public std::runtime_error {
 public:
  enum class Problem {
    Unreadable,    // cannot open or read the file; a writer that cannot create or write its output
    NotRecording,  // the magic is not "SUBSTEPREC"
    Version,       // a version this build does not read
    Truncated,     // the file ends before its footer
    Corrupt,       // the checksum or the end mark does not match
    TooLarge,      // the file beyond maxBytes, or a count beyond its limit
    Malformed,     // well-sealed but inconsistent (metadata, indices, order): not written by this format's writer
  };
  RecordingError(Problem p, const std::string& message) : std::runtime_error(message), problem_(p) {}
  Problem problem() const { return problem_; }

 private:
  Problem problem_;
};
const char* problemName(RecordingError::Problem p);  // "truncated", "corrupt", ...

// Writes a recording under `path`.part<pid> (the temporary name of every output, app/common.h,
// so that a stale one is cleaned up the same way) and renames it over `path` on commit(). The
// metadata must be an object with "bodies" and "joints" (the model's counts: every frame has
// that many) and "panels" (an array: frames name a panel by index); recordingMeta (lab/record.h)
// builds the whole of it. Throws RecordingError (Unreadable) when the file cannot be created or
// written, std::invalid_argument for metadata or a frame that does not fit.
class RecordingWriter {
 public:
  RecordingWriter(const std::string& path, const nlohmann::json& meta);
  ~RecordingWriter();  // removes the temporary unless committed
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;

  void add(int panel, const Snapshot& s);
  void commit();

  const std::string& path() const { return path_; }
  const std::string& tempPath() const { return temp_; }
  long long frames() const { return frames_; }
  uint64_t bytes() const { return bytes_; }  // written so far (the footer too, once committed)
  bool committed() const { return committed_; }

 private:
  void write(const std::string& bytes, bool hashed = true);
  std::string path_, temp_;
  std::FILE* file_ = nullptr;
  XXH3_state_s* hash_ = nullptr;
  size_t bodies_ = 0, joints_ = 0, panels_ = 0;
  long long frames_ = 0;
  uint64_t bytes_ = 0;
  bool committed_ = false;
  std::string buf_;
};

struct Recording {
  nlohmann::json meta;
  std::vector<std::vector<Snapshot>> panels;  // per panel of meta["panels"], its frames in step order
  std::string file;                           // the name messages use
  long long frames() const;
};

// Reads a whole recording, or throws RecordingError: nothing is half-loaded. A file beyond
// maxBytes is refused before it is read.
Recording readRecording(const std::string& path, size_t maxBytes = kDefaultMaxRecordingBytes);
// The same from bytes in memory; `name` is what messages call it.
Recording parseRecording(const std::string& bytes, const std::string& name);

// The scene a recording carries (meta.scene.text, parsed with meta.scene.base_dir for its meshes),
// so that a recording needs no scene file beside it. Throws RecordingError naming the recording
// (Malformed) when the metadata has no scene, the scene does not parse, or its body count is not
// the recording's.
Scene recordingScene(const Recording& r, const SceneLimits& lim = {});

// An observer that records a run as one panel: the state at t = 0, every `every`-th finite step
// and the last planned one. Substep's World gives contacts and joint impulses (takeSnapshot of the
// world); a peer engine its bodies and joint errors.
class RecordingObserver final : public RunObserver {
 public:
  RecordingObserver(RecordingWriter& writer, const Model& model, int panel, long long every, long long planned)
      : writer_(writer), model_(model), panel_(panel), every_(every < 1 ? 1 : every), planned_(planned) {}
  void begin(const Engine& e) override;
  void observe(const Engine& e, const StepRecord& r) override;

 private:
  void take(const Engine& e);
  RecordingWriter& writer_;
  const Model& model_;
  int panel_;
  long long every_, planned_;
};

}  // namespace substep
