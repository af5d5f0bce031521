// The named effects' characteristics on the diagnosis page (diagnose.h, EffectCurve): each curve of
// the diagnosed model with its band of two standard errors, beside the base model's.
#include <algorithm>
#include <cmath>
#include <string>

#include "diagnose_report_internal.h"

namespace strokelab::report::diagnose_internal {

Figure CurvesFigure(const std::vector<EffectCurve>& curves) {
  Figure fig{"curves", "The added physics as curves", {}, {}, ""};
  if (curves.empty()) {
    fig.caption = "Nothing was named, so there is no characteristic to draw.";
    return fig;
  }
  bool any_band = false;
  std::string widths;  // the bands' largest half-widths, in words
  for (const EffectCurve& c : curves) {
    double widest = 0.0;
    plot::Series base = Line("base model", kBaseColor, true), diagnosed = Line("diagnosed model", kChosenColor);
    plot::Series low = Line("+-2 standard errors", kChosenColor, true), high = Line("", kChosenColor, true);
    low.line_width = high.line_width = 1.0;
    for (size_t i = 0; i < c.x.size(); ++i) {
      base.x.push_back(c.x[i]);
      base.y.push_back(c.base_y[i]);
      diagnosed.x.push_back(c.x[i]);
      diagnosed.y.push_back(c.y[i]);
      low.x.push_back(c.x[i]);
      high.x.push_back(c.x[i]);
      low.y.push_back(c.y[i] - 2.0 * c.y_se[i]);  // NaN (no error known) breaks the line
      high.y.push_back(c.y[i] + 2.0 * c.y_se[i]);
      any_band = any_band || std::isfinite(c.y_se[i]);
      if (std::isfinite(c.y_se[i])) widest = std::max(widest, 2.0 * c.y_se[i]);
    }
    widths += (widths.empty() ? "" : "; ") + c.y_label + " +-" + Num(widest, 2) + " at most";
    const std::vector<plot::Series> series = {base, diagnosed, low, high};
    plot::Axes axes = MakeAxes(c.title, c.x_label, c.y_label, 560, 400);
    PadRange(series, false, false, 0.08, 0.25, &axes.y_min, &axes.y_max);
    fig.svgs.push_back(plot::LinePlot(series, axes));
  }
  fig.caption = std::string("Each added force law as the quantity a transducer analyser reports, over the range the "
                            "records reach (") + curves.front().range +
                "). The band is the diagnosed curve +-2 standard errors, from the fit's covariance of its "
                "parameters (delta method)" +
                (any_band ? " (" + widths + ": a band narrower than the line is not drawn apart from it)."
                          : "; no standard error is known here (a parameter is not identifiable).");
  return fig;
}

}  // namespace strokelab::report::diagnose_internal
