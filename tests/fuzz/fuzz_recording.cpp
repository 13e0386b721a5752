// libFuzzer target: a recording from bytes (physics/recording.h). What must hold for every input
// (docs/recordings.md): no crash, no sanitizer report, no hang, no exception but RecordingError,
// and a recording that is accepted is whole (every frame of the metadata's body and joint counts,
// every manifold within its frame). Most mutations break the checksum, so each input is also
// parsed once more with its checksum recomputed: the structure checks behind it get fuzzed too.
//   build: scripts/test --fuzz (clang 14, -fsanitize=fuzzer,address,undefined)
//   seeds: make_recording_seeds writes small valid recordings before the campaign
#include "physics/recording.h"

#include <xxhash.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace {

[[noreturn]] void finding(const char* where, const std::string& what) {
  std::fprintf(stderr, "fuzz_recording: %s: %s\n", where, what.c_str());
  std::abort();
}

void check(const std::string& bytes) {
  using namespace substep;
  Recording r;
  try {
    r = parseRecording(bytes, "fuzz.rec");
  } catch (const RecordingError&) {
    return;  // refused with its reason: the contract
  } catch (const std::exception& e) {
    finding("parseRecording threw other than RecordingError", e.what());
  }
  const size_t bodies = r.meta.at("bodies").get<size_t>(), joints = r.meta.at("joints").get<size_t>();
  if (r.panels.size() != r.meta.at("panels").size()) finding("accepted", "a panel count unlike the metadata's");
  for (const auto& panel : r.panels)
    for (const Snapshot& s : panel) {
      if (s.state.bodies.size() != bodies || s.joints.size() != joints) finding("accepted", "a frame of other counts");
      for (const ManifoldSnap& m : s.manifolds)
        if (m.a < 0 || m.b < 0 || static_cast<size_t>(m.a) >= bodies || static_cast<size_t>(m.b) >= bodies ||
            static_cast<size_t>(m.first) + static_cast<size_t>(m.count) > s.contacts.size())
          finding("accepted", "a manifold beyond its frame");
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  check(bytes);
  // The footer is the last 27 bytes: tag, frame count, checksum (of everything before it), end mark.
  if (size >= 45) {
    std::string sealed = bytes;
    const size_t at = size - 27;
    const uint64_t h = XXH3_64bits(sealed.data(), at + 9);
    for (int i = 0; i < 8; ++i) sealed[at + 9 + static_cast<size_t>(i)] = static_cast<char>((h >> (8 * i)) & 0xff);
    check(sealed);
  }
  return 0;
}
