#include "physics/utf8.h"

#include "physics/limits.h"

namespace substep {

namespace {

// The length of the well-formed UTF-8 character at s[i] (Unicode's table 3-7: no overlong form,
// no surrogate, nothing past U+10FFFF), 0 if the byte there starts none.
size_t characterLength(const std::string& s, size_t i) {
  const auto at = [&](size_t k) { return i + k < s.size() ? static_cast<unsigned char>(s[i + k]) : 0; };
  const auto tail = [&](size_t k) { return at(k) >= 0x80 && at(k) <= 0xbf; };
  const unsigned char c = at(0);
  if (c < 0x80) return 1;
  if (c >= 0xc2 && c <= 0xdf) return tail(1) ? 2 : 0;
  if (c >= 0xe0 && c <= 0xef) {
    const unsigned char lo = c == 0xe0 ? 0xa0 : 0x80, hi = c == 0xed ? 0x9f : 0xbf;
    return at(1) >= lo && at(1) <= hi && tail(2) ? 3 : 0;
  }
  if (c >= 0xf0 && c <= 0xf4) {
    const unsigned char lo = c == 0xf0 ? 0x90 : 0x80, hi = c == 0xf4 ? 0x8f : 0xbf;
    return at(1) >= lo && at(1) <= hi && tail(2) && tail(3) ? 4 : 0;
  }
  return 0;
}

}  // namespace

std::string validUtf8(const std::string& s) {
  std::string r;
  r.reserve(s.size());
  for (size_t i = 0; i < s.size();) {
    const size_t n = characterLength(s, i);
    if (n == 0) {
      r += "\xef\xbf\xbd";  // U+FFFD
      ++i;
    } else {
      r.append(s, i, n);
      i += n;
    }
  }
  return r;
}

std::string utf8Prefix(const std::string& s, size_t max) {
  const std::string v = validUtf8(s);
  size_t end = 0;
  while (end < v.size() && end + characterLength(v, end) <= max) end += characterLength(v, end);
  return v.substr(0, end);
}

std::string messageValue(const std::string& s) {
  return s.size() > limits::kMaxMessageValue ? utf8Prefix(s, limits::kMaxMessageValue) + "..." : validUtf8(s);
}

}  // namespace substep
