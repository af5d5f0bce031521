// Helpers of the plot tests: a small XML well-formedness checker, and functions that read our own
// SVG output back (groups, texts, attributes, the plot area).
#pragma once

#include <cctype>
#include <cmath>
#include <limits>
#include <regex>
#include <string>
#include <utility>
#include <vector>

#include "strokelab/plot/svg_plot.h"

namespace strokelab::plot::svg_test {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// ---------------------------------------------------------------------------------------------
// A small XML well-formedness checker: one root element, tags nest and close in order, attribute
// values are quoted, text and attribute values use only the predefined entities. Returns "" when
// well formed, else what is wrong and where.

inline bool IsNameChar(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == ':' || c == '.';
}

inline std::string CheckEntities(const std::string& s, size_t offset) {
  static const std::regex kEntity("^&(amp|lt|gt|quot|apos|#[0-9]+|#x[0-9a-fA-F]+);");
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '<') return "bare '<' at " + std::to_string(offset + i);
    if (s[i] == '&' && !std::regex_search(s.substr(i, 12), kEntity))
      return "bad entity at " + std::to_string(offset + i);
    if (static_cast<unsigned char>(s[i]) < 0x20 && s[i] != '\n' && s[i] != '\t' && s[i] != '\r') {
      return "control character at " + std::to_string(offset + i);
    }
  }
  return "";
}

inline std::string XmlProblem(const std::string& xml) {
  std::vector<std::string> open;
  int roots = 0;
  size_t i = 0;
  while (i < xml.size()) {
    const size_t lt = xml.find('<', i);
    const std::string text = xml.substr(i, lt == std::string::npos ? std::string::npos : lt - i);
    if (std::string e = CheckEntities(text, i); !e.empty()) return e;
    if (open.empty() && text.find_first_not_of(" \t\r\n") != std::string::npos)
      return "text outside the root at " + std::to_string(i);
    if (lt == std::string::npos) break;
    i = lt;
    if (xml.compare(i, 2, "<?") == 0 || xml.compare(i, 4, "<!--") == 0) {
      const std::string end = xml[i + 1] == '?' ? "?>" : "-->";
      const size_t e = xml.find(end, i);
      if (e == std::string::npos) return "unterminated declaration at " + std::to_string(i);
      i = e + end.size();
      continue;
    }
    const bool closing = xml.compare(i, 2, "</") == 0;
    size_t p = i + (closing ? 2 : 1);
    const size_t name_begin = p;
    while (p < xml.size() && IsNameChar(xml[p])) ++p;
    const std::string name = xml.substr(name_begin, p - name_begin);
    if (name.empty()) return "missing tag name at " + std::to_string(i);
    if (closing) {
      if (p >= xml.size() || xml[p] != '>') return "malformed end tag at " + std::to_string(i);
      if (open.empty() || open.back() != name)
        return "</" + name + "> does not close the open element at " + std::to_string(i);
      open.pop_back();
      i = p + 1;
      continue;
    }
    if (open.empty() && ++roots > 1) return "second root element at " + std::to_string(i);
    while (true) {  // attributes
      while (p < xml.size() && std::isspace(static_cast<unsigned char>(xml[p]))) ++p;
      if (p >= xml.size()) return "unterminated tag <" + name;
      if (xml.compare(p, 2, "/>") == 0) {
        p += 2;
        break;
      }
      if (xml[p] == '>') {
        open.push_back(name);
        ++p;
        break;
      }
      const size_t attr_begin = p;
      while (p < xml.size() && IsNameChar(xml[p])) ++p;
      if (p == attr_begin || xml.compare(p, 2, "=\"") != 0)
        return "malformed attribute in <" + name + " at " + std::to_string(p);
      const size_t value_end = xml.find('"', p + 2);
      if (value_end == std::string::npos) return "unterminated attribute value at " + std::to_string(p);
      if (std::string e = CheckEntities(xml.substr(p + 2, value_end - p - 2), p + 2); !e.empty()) return e;
      p = value_end + 1;
    }
    i = p;
  }
  if (!open.empty()) return "<" + open.back() + "> is never closed";
  if (roots != 1) return "no root element";
  return "";
}

// ---------------------------------------------------------------------------------------------
// Reading our own output back.

// The content of the first <g class="name"> ... </g> (these groups hold no nested <g>).
inline std::string Group(const std::string& svg, const std::string& css_class) {
  const std::string open = "<g class=\"" + css_class + "\"";
  const size_t b = svg.find(open);
  if (b == std::string::npos) return "";
  const size_t e = svg.find("</g>", b);
  return svg.substr(b, e - b);
}

inline std::vector<std::string> Texts(const std::string& svg_part) {
  static const std::regex kText("<text[^>]*>([^<]*)</text>");
  std::vector<std::string> out;
  for (std::sregex_iterator it(svg_part.begin(), svg_part.end(), kText), end; it != end; ++it) out.push_back((*it)[1]);
  return out;
}

inline int Count(const std::string& s, const std::string& what) {
  int n = 0;
  for (size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

inline std::vector<std::string> TickLabels(const std::string& svg, const char* axis) { return Texts(Group(svg, axis)); }

inline double Attribute(const std::string& element, const std::string& name) {
  const std::regex re(" " + name + "=\"([-0-9.e]+)\"");
  std::smatch m;
  if (!std::regex_search(element, m, re)) return kNaN;
  return std::stod(m[1]);
}

struct Rect {
  double x, y, width, height;
};

// The plot area, as the clip path's rectangle.
inline Rect PlotArea(const std::string& svg) {
  const size_t b = svg.find("<clipPath");
  const std::string clip = svg.substr(b, svg.find("</clipPath>", b) - b);
  return {Attribute(clip, "x"), Attribute(clip, "y"), Attribute(clip, "width"), Attribute(clip, "height")};
}

// The start tags <tag ...> in svg_part. Found by hand, not by std::regex: libstdc++'s matcher recurses
// once per character of [^>]*, and a polyline's points (tens of thousands of characters) overflowed the
// stack of an unoptimised ASan build (LinePlotTest.DecimationKeepsExtremes).
inline std::vector<std::string> Elements(const std::string& svg_part, const std::string& tag) {
  std::vector<std::string> out;
  const std::string open = "<" + tag;
  for (size_t at = svg_part.find(open); at != std::string::npos; at = svg_part.find(open, at + 1)) {
    const size_t after = at + open.size();
    const bool longer_name =
        after < svg_part.size() && (std::isalnum(static_cast<unsigned char>(svg_part[after])) || svg_part[after] == '_');
    if (longer_name) continue;
    const size_t close = svg_part.find('>', after);
    if (close == std::string::npos) break;
    out.push_back(svg_part.substr(at, close - at + 1));
  }
  return out;
}

inline Series Line(std::vector<double> x, std::vector<double> y, std::string label = "") {
  Series s;
  s.x = std::move(x);
  s.y = std::move(y);
  s.label = std::move(label);
  return s;
}

inline std::vector<double> Linspace(double a, double b, int n) {
  std::vector<double> v(n);
  for (int i = 0; i < n; ++i) v[i] = a + (b - a) * i / (n - 1);
  return v;
}

}  // namespace strokelab::plot::svg_test
