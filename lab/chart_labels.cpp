#include "lab/chart_labels.h"

namespace substep::lab {

Box labelBox(const std::string& text, double x, double y) {
  return {x, y - kLabelHeight / 2, x + kLabelCharWidth * static_cast<double>(text.size()), y + kLabelHeight / 2};
}

namespace {

// Where a label may go around its point, best first: to the upper right (as gnuplot's own offset
// put them), right, lower right, then the left side, above, below, and a step further out.
bool place(const std::string& text, double px, double py, const std::vector<Box>& taken, const Box& area, LabelPlacement& out) {
  const double w = kLabelCharWidth * static_cast<double>(text.size()), gap = 7;
  for (double far : {1.0, 2.2}) {
    const double d = gap * far, up = kLabelHeight * 0.75 * far;
    const double spots[][2] = {{px + d, py - up}, {px + d, py},          {px + d, py + up},
                               {px - d - w, py - up}, {px - d - w, py}, {px - d - w, py + up},
                               {px - w / 2, py - up - kLabelHeight / 2}, {px - w / 2, py + up + kLabelHeight / 2}};
    for (const auto& s : spots) {
      const Box b = labelBox(text, s[0], s[1]);
      if (!b.inside(area)) continue;
      bool clear = true;
      for (const Box& t : taken)
        if (b.overlaps(t)) {
          clear = false;
          break;
        }
      if (!clear) continue;
      out.x = s[0], out.y = s[1], out.box = b;
      return true;
    }
  }
  return false;
}

}  // namespace

std::vector<LabelPlacement> placeLabels(const std::vector<LabelRequest>& requests, std::vector<Box> taken, const Box& area) {
  std::vector<LabelPlacement> out(requests.size());
  // Full labels first, everywhere: a tag never takes a place a full label could have had.
  for (size_t i = 0; i < requests.size(); ++i) {
    if (requests[i].text.empty() || !place(requests[i].text, requests[i].x, requests[i].y, taken, area, out[i])) continue;
    out[i].kind = LabelPlacement::Kind::Text;
    taken.push_back(out[i].box);
  }
  int number = 0;
  for (size_t i = 0; i < requests.size(); ++i) {
    if (requests[i].text.empty() || out[i].kind == LabelPlacement::Kind::Text) continue;
    out[i].number = ++number;
    if (!place(std::to_string(number), requests[i].x, requests[i].y, taken, area, out[i])) continue;
    out[i].kind = LabelPlacement::Kind::Tag;
    taken.push_back(out[i].box);
  }
  return out;
}

}  // namespace substep::lab
