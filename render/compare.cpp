#include "render/compare.h"

#include <stdexcept>

namespace substep::render {

std::vector<CompareSpec> parseCompareSpecs(const std::string& s) {
  const std::string usage = " (expected e.g. --compare a2:m=4,a5:n=4)";
  std::vector<MethodSpec> methods;
  try {
    methods = parseMethodSpecs(s);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("--compare: " + std::string(e.what()));
  }
  if (methods.size() < 2 || methods.size() > 4)
    throw std::invalid_argument("--compare: expected 2 to 4 panels separated by commas (value lists a|b count "
                                "as one panel each), got " + std::to_string(methods.size()) + usage);
  std::vector<CompareSpec> specs;
  for (const MethodSpec& m : methods) {
    if (!m.peer.empty())
      throw std::invalid_argument("--compare: \"" + m.text + "\": the " + m.peer +
                                  " peer is measured by the lab (substep sweep, substep atlas), not drawn here; "
                                  "panels take substep's algorithms a1 ... a5, soft");
    specs.push_back({m.text, m.overrides});
  }
  return specs;
}

}  // namespace substep::render
