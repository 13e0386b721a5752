// Text quoted in messages (a value from a file, a body, a path) may be any bytes, and a message
// is shown, logged and sent in JSON, which must be UTF-8: each byte that does not start a
// well-formed character becomes U+FFFD, and values are cut at a character's boundary.
#pragma once

#include <cstddef>
#include <string>

namespace substep {

std::string validUtf8(const std::string& s);
// validUtf8(s) cut to at most `max` bytes, at a character's boundary.
std::string utf8Prefix(const std::string& s, size_t max);
// A value as a message quotes it: cut after limits::kMaxMessageValue bytes, with "..." then.
std::string messageValue(const std::string& s);

}  // namespace substep
