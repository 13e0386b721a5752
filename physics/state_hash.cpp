#include "physics/state_hash.h"

#include <xxhash.h>

#include <cstdio>
#include <cstring>

namespace substep {

namespace {

// The 13 doubles of a body, as bits: -0 and +0 differ, as a re-run that is not bit-identical should.
void bodyBits(const BodyState& b, double out[13]) {
  const double v[13] = {b.x.x(), b.x.y(), b.x.z(), b.q.w(), b.q.x(), b.q.y(), b.q.z(),
                        b.v.x(), b.v.y(), b.v.z(), b.w.x(), b.w.y(), b.w.z()};
  std::memcpy(out, v, sizeof v);
}

}  // namespace

uint64_t bodyHash(const BodyState& b) {
  double bits[13];
  bodyBits(b, bits);
  return XXH3_64bits(bits, sizeof bits);
}

uint64_t stateHash(const State& s) {
  XXH3_state_t* st = XXH3_createState();
  XXH3_64bits_reset(st);
  const long long step = s.step;
  XXH3_64bits_update(st, &step, sizeof step);
  XXH3_64bits_update(st, &s.time, sizeof s.time);
  for (const BodyState& b : s.bodies) {
    double bits[13];
    bodyBits(b, bits);
    XXH3_64bits_update(st, bits, sizeof bits);
  }
  const uint64_t h = XXH3_64bits_digest(st);
  XXH3_freeState(st);
  return h;
}

std::string hashText(uint64_t h) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

std::optional<uint64_t> parseHash(const std::string& text) {
  if (text.size() != 16 || text.find_first_not_of("0123456789abcdef") != std::string::npos) return std::nullopt;
  return static_cast<uint64_t>(std::stoull(text, nullptr, 16));
}

}  // namespace substep
