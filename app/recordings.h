// A recording (physics/recording.h) opened for replay: its scene, a panel setup per recorded panel
// and their frames, ready for RenderSession::setRecorded. `substep render x.rec` and `substep serve
// --open x.rec` (and the server's uploads) open recordings through here, so a recording is refused
// the same way everywhere: exit 2 (UsageError) or 400, with the reader's reason.
#pragma once

#include "physics/recording.h"
#include "render/session.h"

#include <memory>
#include <string>
#include <vector>

namespace substep::app {

struct OpenedRecording {
  std::string file;
  std::shared_ptr<const Scene> scene;
  std::vector<render::PanelSetup> panels;   // each recorded panel's settings, named by its method
  std::vector<std::vector<Snapshot>> frames;
  double seconds = 0;                       // the last frame's time [s]
  long long every = 1;
};

// Whether a command's scene argument names a recording (by its ".rec" extension).
bool isRecordingPath(const std::string& path);
// Throws RecordingError (the reader's), or RecordingError Malformed for settings this build
// cannot make a World with.
OpenedRecording openRecording(Recording r);
// readRecording + openRecording, the errors as UsageError naming the file.
OpenedRecording openRecordingFile(const std::string& path, size_t maxBytes = kDefaultMaxRecordingBytes);

}  // namespace substep::app
