#include "physics/state_hash.h"

#include <xxhash.h>

#include <algorithm>
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

std::string contentHash(const std::string& bytes) {
  const XXH128_hash_t h = XXH3_128bits(bytes.data(), bytes.size());
  return hashText(h.high64) + hashText(h.low64);
}

StateHashes::StateHashes(const Model& model, long long plannedSteps, long long every) {
  h_.every = every > 0 ? every : std::max(1LL, (plannedSteps + RunHashes::kMaxStepHashes - 1) / RunHashes::kMaxStepHashes);
  for (size_t i = 0; i < model.bodies.size(); ++i)
    if (!model.bodies[i].isStatic) h_.dynamic.push_back(static_cast<int>(i));
  keepBodies_ = h_.dynamic.size() <= RunHashes::kMaxBodyHashed;
}

void StateHashes::bodiesAt(long long step, const State& s) {
  std::vector<uint32_t> b;
  b.reserve(h_.dynamic.size());
  for (int i : h_.dynamic) b.push_back(static_cast<uint32_t>(bodyHash(s.bodies[static_cast<size_t>(i)])));
  h_.bodies.emplace_back(step, std::move(b));
}

void StateHashes::begin(const Engine& e) { h_.last = stateHash(e.state()); }

void StateHashes::observe(const Engine& e, const StepRecord& r) {
  if (r.step % h_.every == 0) h_.steps.emplace_back(r.step, stateHash(e.state()));
  if (keepBodies_ && (r.step & (r.step - 1)) == 0) bodiesAt(r.step, e.state());
}

void StateHashes::end(const Engine& e, const RunOutcome& o) {
  h_.last = stateHash(e.state());
  if (o.steps > 0 && (h_.steps.empty() || h_.steps.back().first != o.steps)) h_.steps.emplace_back(o.steps, h_.last);
  if (o.steps > 0 && h_.dynamic.size() <= 16 * RunHashes::kMaxBodyHashed &&
      (h_.bodies.empty() || h_.bodies.back().first != o.steps))
    bodiesAt(o.steps, e.state());
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
