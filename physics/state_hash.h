// A state's fingerprint: XXH3 (libxxhash) of the bit patterns of every body's position,
// orientation and velocities, and of the step count and time. Two runs agree to the last bit or
// their hashes differ, so records can be re-run and checked (substep rerun) and the trajectory
// table test can hold every scene under every algorithm in a few bytes each.
#pragma once

#include "physics/model.h"
#include "physics/run.h"
#include "physics/state.h"

#include <cstdint>
#include <optional>
#include <string>

namespace substep {

uint64_t bodyHash(const BodyState& b);
// Over the step, the time and every body's hash in order.
uint64_t stateHash(const State& s);
// 16 hex digits, and back (nullopt for anything else).
std::string hashText(uint64_t h);
std::optional<uint64_t> parseHash(const std::string& text);
// XXH3-128 of bytes (a scene file's content): 32 hex digits.
std::string contentHash(const std::string& bytes);

// What a record keeps of a run to check a re-run against: the state's hash after every
// `every`-th step and after the last, and each dynamic body's hash (its low 32 bits) at steps
// 1, 2, 4, 8, ... and the last, so that a re-run that differs can name the first step and the
// bodies that differ there. Body hashes before the last are kept for scenes of at most
// kMaxBodyHashed dynamic bodies, the last for 16 times as many (a 1000-box pile would otherwise
// make every sweep record 100 KB longer).
struct RunHashes {
  static constexpr long long kMaxStepHashes = 1024;
  static constexpr size_t kMaxBodyHashed = 256;
  long long every = 1;
  std::vector<std::pair<long long, uint64_t>> steps;                  // (step, state hash)
  std::vector<std::pair<long long, std::vector<uint32_t>>> bodies;    // (step, per dynamic body)
  std::vector<int> dynamic;                                           // the bodies `bodies` hashes, in order
  uint64_t last = 0;                                                  // the state's hash at the end
};

class StateHashes final : public RunObserver {
 public:
  // Every ceil(plannedSteps / kMaxStepHashes)-th step, or every `every`-th when given.
  StateHashes(const Model& model, long long plannedSteps, long long every = 0);
  void begin(const Engine& e) override;
  void observe(const Engine& e, const StepRecord& r) override;
  void end(const Engine& e, const RunOutcome& o) override;
  const RunHashes& hashes() const { return h_; }

 private:
  void bodiesAt(long long step, const State& s);
  RunHashes h_;
  bool keepBodies_;
};

}  // namespace substep
