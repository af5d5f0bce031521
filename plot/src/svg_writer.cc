// The SVG writer: numbers and text as SVG attributes and elements, the estimated width of text,
// and XML escaping (EscapeXml, public).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <string_view>

#include "strokelab/plot/svg_plot.h"
#include "svg_plot_internal.h"

namespace strokelab::plot::svg_internal {
namespace {

// Number of characters (UTF-8 code points) in `s`.
size_t CodePoints(std::string_view s) {
  return std::count_if(s.begin(), s.end(), [](char c) { return (static_cast<unsigned char>(c) & 0xC0) != 0x80; });
}

}  // namespace

std::string Num(double v, int decimals) {
  if (!std::isfinite(v)) v = 0.0;
  v = std::clamp(v, -1e6, 1e6);
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  std::string s = buf;
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  if (s == "-0") s = "0";
  return s;
}

double TextWidthPx(std::string_view s, double font_px) {
  return static_cast<double>(CodePoints(s)) * kGlyphWidthEm * font_px;
}

std::string Text(double x, double y, const std::string& content, double font_px, const char* anchor,
                 std::string_view css_class) {
  Tag t("text");
  if (!css_class.empty()) t.Attr("class", css_class);
  t.Attr("x", x).Attr("y", y).Attr("font-size", font_px).Attr("text-anchor", anchor);
  return t.Wrap(content);
}

PlacedLine FitLine(std::string_view text, double font_px, double center, double lo, double hi, double width_factor) {
  const double width = width_factor * TextWidthPx(text, font_px);
  if (width > hi - lo) return {(lo + hi) / 2, std::max(8.0, font_px * (hi - lo) / width)};
  return {std::clamp(center, lo + width / 2, hi - width / 2), font_px};
}

}  // namespace strokelab::plot::svg_internal

namespace strokelab::plot {

std::string EscapeXml(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\t':
      case '\n':
      case '\r':
        out += c;
        break;
      default:
        // Control characters are not allowed in XML 1.0 at all, even escaped: drop them.
        if (static_cast<unsigned char>(c) >= 0x20) out += c;
    }
  }
  return out;
}

}  // namespace strokelab::plot
