#include "app/recordings.h"

#include "app/common.h"
#include "physics/settings_json.h"

#include <filesystem>

namespace substep::app {

bool isRecordingPath(const std::string& path) { return std::filesystem::path(path).extension() == ".rec"; }

OpenedRecording openRecording(Recording r) {
  OpenedRecording o;
  o.file = r.file;
  o.scene = std::make_shared<const Scene>(recordingScene(r));
  const nlohmann::json& panels = r.meta.at("panels");
  for (size_t i = 0; i < panels.size(); ++i) {
    const nlohmann::json& p = panels[i];
    const std::string where = r.file + ": panels[" + std::to_string(i) + "].settings";
    render::PanelSetup s;
    const std::string engine = p.value("engine", "substep");
    try {
      if (engine == "substep") {
        s.settings = resolvedFromJson(p.at("settings"), where);
      } else {  // a peer's panel is drawn from its frames, never stepped: substep's defaults at its h
        s.settings = resolve(SolverOverrides{});
        s.settings.dt = p.at("settings").at("dt").get<double>();
      }
    } catch (const std::exception& e) {
      throw RecordingError(RecordingError::Problem::Malformed, e.what());
    }
    s.name = p.value("method", p.value("name", std::string()));
    if (engine != "substep" && s.name.rfind(engine, 0) != 0) s.name = engine + (s.name.empty() ? "" : " " + s.name);
    o.panels.push_back(std::move(s));
  }
  for (const auto& f : r.panels)
    if (!f.empty()) o.seconds = std::max(o.seconds, f.back().state.time);
  o.every = r.meta.value("every", 1LL);
  o.frames = std::move(r.panels);
  return o;
}

OpenedRecording openRecordingFile(const std::string& path, size_t maxBytes) {
  try {
    return openRecording(readRecording(path, maxBytes));
  } catch (const RecordingError& e) {
    throw UsageError(e.what());
  } catch (const SceneError& e) {
    throw UsageError(path + ": its scene: " + e.what());
  }
}

}  // namespace substep::app
