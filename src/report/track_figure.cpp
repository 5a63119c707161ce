// The map page's picture of the navigation before and after drift correction: a top view in SVG
// with axes in metres, a scale bar and a north arrow (world frame local ENU: +y is north).
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "page.hpp"

namespace sonar3d::report_page {

namespace {

// The 1-2-5 step nearest above `raw`.
double nice_step(double raw) {
  if (!(raw > 0) || !std::isfinite(raw)) return 1;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * p >= raw) return m * p;
  }
  return 10 * p;
}

std::string num(double v, int decimals = 1) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

// A tick label: as many decimals as the step needs.
std::string tick_label(double v, double step) {
  const int d = step >= 1 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  return num(std::abs(v) < 0.5 * step * 1e-6 ? 0.0 : v, d);
}

}  // namespace

std::string track_svg(const std::vector<Eigen::Vector2d>& before,
                      const std::vector<Eigen::Vector2d>& after) {
  const double W = 720, H = 520, left = 70, right = 20, top = 20, bottom = 60;
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  for (const auto* track : {&before, &after}) {
    for (const Eigen::Vector2d& p : *track) {
      if (!p.allFinite()) continue;
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
  }
  if (!(hi.x() >= lo.x())) lo = hi = Eigen::Vector2d::Zero();
  // Equal scale on both axes (a map), the extent padded by 5 % and at least 1 m.
  Eigen::Vector2d centre = 0.5 * (lo + hi), half = 0.5 * (hi - lo) * 1.05;
  half = half.cwiseMax(0.5);
  const double pw = W - left - right, ph = H - top - bottom;
  const double scale = std::min(pw / (2 * half.x()), ph / (2 * half.y()));  // px per metre
  half = Eigen::Vector2d(pw / scale / 2, ph / scale / 2);
  lo = centre - half;
  hi = centre + half;
  auto X = [&](double x) { return left + (x - lo.x()) * scale; };
  auto Y = [&](double y) { return top + (hi.y() - y) * scale; };

  std::string s =
      "<svg xmlns=\"http://www.w3.org/2000/svg\" class=\"track-figure\" viewBox=\"0 0 " +
      num(W, 0) + " " + num(H, 0) + "\" width=\"" + num(W, 0) + "\" height=\"" + num(H, 0) +
      "\" font-family=\"sans-serif\" font-size=\"12\">";
  s += "<rect x=\"" + num(left) + "\" y=\"" + num(top) + "\" width=\"" + num(pw) + "\" height=\"" +
       num(ph) + "\" fill=\"#fafafa\" stroke=\"#888\"/>";
  // Axes: ticks every `step` metres, labelled in metres.
  const double step = nice_step(std::max(hi.x() - lo.x(), hi.y() - lo.y()) / 8);
  s += "<g class=\"axis-x\">";
  for (double x = std::ceil(lo.x() / step) * step; x <= hi.x() + 1e-9; x += step) {
    s += "<line x1=\"" + num(X(x)) + "\" y1=\"" + num(top + ph) + "\" x2=\"" + num(X(x)) +
         "\" y2=\"" + num(top + ph + 5) + "\" stroke=\"#444\"/><text x=\"" + num(X(x)) + "\" y=\"" +
         num(top + ph + 18) + "\" text-anchor=\"middle\">" + tick_label(x, step) + "</text>";
  }
  s += "<text x=\"" + num(left + pw / 2) + "\" y=\"" + num(H - 22) +
       "\" text-anchor=\"middle\">x [m] (East)</text></g>";
  s += "<g class=\"axis-y\">";
  for (double y = std::ceil(lo.y() / step) * step; y <= hi.y() + 1e-9; y += step) {
    s += "<line x1=\"" + num(left - 5) + "\" y1=\"" + num(Y(y)) + "\" x2=\"" + num(left) +
         "\" y2=\"" + num(Y(y)) + "\" stroke=\"#444\"/><text x=\"" + num(left - 8) + "\" y=\"" +
         num(Y(y) + 4) + "\" text-anchor=\"end\">" + tick_label(y, step) + "</text>";
  }
  s += "<text transform=\"translate(16 " + num(top + ph / 2) +
       ") rotate(-90)\" text-anchor=\"middle\">y [m] (North)</text></g>";
  // The tracks, at most 4,000 vertices each.
  auto polyline = [&](const std::vector<Eigen::Vector2d>& t, const char* cls, const char* style) {
    if (t.empty()) return;
    const std::size_t stride = std::max<std::size_t>(1, t.size() / 4000);
    s += std::string("<polyline class=\"") + cls + "\" fill=\"none\" " + style + " points=\"";
    for (std::size_t k = 0; k < t.size(); k += stride) {
      if (t[k].allFinite()) s += num(X(t[k].x())) + "," + num(Y(t[k].y())) + " ";
    }
    s += "\"/>";
  };
  polyline(before, "track-before",
           "stroke=\"#d62728\" stroke-width=\"1.5\" stroke-dasharray=\"5 3\"");
  polyline(after, "track-after", "stroke=\"#1f77b4\" stroke-width=\"1.5\"");
  // Legend.
  const double lx = left + 12, ly = top + 16;
  s += "<g class=\"legend\"><line x1=\"" + num(lx) + "\" y1=\"" + num(ly) + "\" x2=\"" +
       num(lx + 24) + "\" y2=\"" + num(ly) +
       "\" stroke=\"#d62728\" stroke-width=\"1.5\" stroke-dasharray=\"5 3\"/><text x=\"" +
       num(lx + 30) + "\" y=\"" + num(ly + 4) + "\">before (as logged)</text><line x1=\"" +
       num(lx) + "\" y1=\"" + num(ly + 18) + "\" x2=\"" + num(lx + 24) + "\" y2=\"" + num(ly + 18) +
       "\" stroke=\"#1f77b4\" stroke-width=\"1.5\"/><text x=\"" + num(lx + 30) + "\" y=\"" +
       num(ly + 22) + "\">after (corrected)</text></g>";
  // Scale bar: one tick step, bottom left inside the frame.
  const double bx = left + 14, by = top + ph - 16, blen = step * scale;
  s += "<g class=\"scale-bar\"><rect x=\"" + num(bx) + "\" y=\"" + num(by - 4) + "\" width=\"" +
       num(blen) + "\" height=\"4\" fill=\"#222\"/><text x=\"" + num(bx + blen / 2) + "\" y=\"" +
       num(by - 8) + "\" text-anchor=\"middle\">" + tick_label(step, step) + " m</text></g>";
  // North arrow (+y), top right inside the frame.
  const double nx = left + pw - 24, ny = top + 14;
  s += "<g class=\"north-arrow\"><polygon points=\"" + num(nx) + "," + num(ny + 6) + " " +
       num(nx - 7) + "," + num(ny + 30) + " " + num(nx) + "," + num(ny + 24) + " " + num(nx + 7) +
       "," + num(ny + 30) + "\" fill=\"#222\"/><text x=\"" + num(nx) + "\" y=\"" + num(ny + 2) +
       "\" text-anchor=\"middle\" font-weight=\"bold\">N</text></g>";
  s += "</svg>";
  return s;
}

}  // namespace sonar3d::report_page
