// Point labels that never overlap (the Pareto chart, lab/chart.cpp). Each point's label is tried
// at eight places around it; one that fits nowhere gets a short tag (its number in the list under
// the chart) tried the same way, and failing that nothing: the list still names it with its
// coordinates. Positions are in pixels of the image, y downwards; text is measured with the
// chart's label font (DejaVu Sans 8 pt under pngcairo: about 6.4 px a character, measured).
#pragma once

#include <string>
#include <vector>

namespace substep::lab {

struct Box {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // [px] left, top, right, bottom
  bool overlaps(const Box& b) const { return x0 < b.x1 && b.x0 < x1 && y0 < b.y1 && b.y0 < y1; }
  bool inside(const Box& b) const { return x0 >= b.x0 && x1 <= b.x1 && y0 >= b.y0 && y1 <= b.y1; }
};

// The box a label of `text` takes with its left end at x and its middle at y (gnuplot centres a
// label on its y).
constexpr double kLabelCharWidth = 7.0;   // [px] a little over the measured 6.4-6.7 for margin
constexpr double kLabelHeight = 12.0;     // [px] the 8 pt font's 9 px with room between lines
Box labelBox(const std::string& text, double x, double y);

struct LabelRequest {
  double x = 0, y = 0;  // the point [px]
  std::string text;     // the full label ("n=4 m=1"); empty: the point needs none
};

struct LabelPlacement {
  enum class Kind { Text, Tag, None } kind = Kind::None;
  int number = 0;       // a label that did not fit: its number in the list (1, 2, ...), shown as its tag
  double x = 0, y = 0;  // the label's (or tag's) left end and middle [px]
  Box box;
};

// Requests in order of priority: earlier ones get the better places. `obstacles` (the point
// markers, notes drawn on the chart) are never covered; every label stays inside `area`.
std::vector<LabelPlacement> placeLabels(const std::vector<LabelRequest>& requests, std::vector<Box> obstacles, const Box& area);

}  // namespace substep::lab
