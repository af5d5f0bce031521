// The Illinois variant of regula falsi (M. Dowell and P. Jarratt, "A modified regula falsi method for
// computing the root of an equation", BIT 11 (1971) 168-174): a bracket [a, b] of a sign change of g,
// cut at the secant point; when the same end is kept twice in a row its value is halved, which gives
// superlinear convergence (order ~1.44) where plain regula falsi keeps one end and converges linearly.
#pragma once

#include <algorithm>
#include <cmath>

namespace strokelab {

struct IllinoisBracket {
  double a, b;    // the bracket's ends, in any order
  double ga, gb;  // g there, of opposite signs (ga != 0; gb may be 0)
  int kept = 0;   // the end kept by the last Update: -1 a, +1 b, 0 none yet

  // The secant point, or the midpoint where it falls outside (a, b) (rounding, ga == gb).
  double Next() const {
    const double x = ga != gb ? (a * gb - b * ga) / (gb - ga) : 0.5 * (a + b);
    return x > std::min(a, b) && x < std::max(a, b) ? x : 0.5 * (a + b);
  }
  // g(x) = gx replaces the end on its side, judged against a's value (b's may be an exact zero); a
  // zero counts as b's side, and the caller stops there.
  bool OnSideOfB(double gx) const { return gx == 0.0 || (gx > 0) != (ga > 0); }
  void Update(double x, double gx) {
    if (OnSideOfB(gx)) {
      b = x;
      gb = gx;
      if (kept == -1) ga *= 0.5;
      kept = -1;
    } else {
      a = x;
      ga = gx;
      if (kept == 1) gb *= 0.5;
      kept = 1;
    }
  }
  double Width() const { return std::abs(b - a); }
};

}  // namespace strokelab
