// A state's fingerprint: XXH3 (libxxhash) of the bit patterns of every body's position,
// orientation and velocities, and of the step count and time. Two runs agree to the last bit or
// their hashes differ, so records can be re-run and checked (substep rerun) and the trajectory
// table test can hold every scene under every algorithm in a few bytes each.
#pragma once

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

}  // namespace substep
