// The refinement's start for |d| (fit.cc, between steps 3 and 4): the best of a grid over step 3's
// bracket, judged by how well the staged model matches the contacting records.
#include <algorithm>
#include <cmath>

#include "fit_internal.h"
#include "strokelab/base/parallel_for.h"
#include "strokelab/identify/fit_orbit.h"

namespace strokelab::fit_internal {
namespace {

using internal::BestMatchingOrbit, internal::MismatchSquared, internal::ModelOrbit;

// Geometric grid over the bracket, both ends included. Nine points put neighbours within 1.15x of
// each other over a bracket of 3x, inside the factor the refinement moves |d| from its start.
constexpr int kStopGridPoints = 9;

// Chi-square of the contacting records' harmonics for `model` (inf when a record has no orbit).
double ContactingChi2(std::span<const RecordAnalysis> analyses, const std::vector<size_t>& records, ResponseKind kind,
                      const ActuatorModel& model, int orders) {
  double chi2 = 0.0;
  for (size_t i : records) {
    const RecordAnalysis& a = analyses[i];
    std::optional<ModelOrbit> orbit;
    try {
      orbit = BestMatchingOrbit(model, a, kind, orders);
    } catch (const std::exception&) {
    }
    if (!orbit) return kInf;
    chi2 += MismatchSquared(a, orbit->harmonics) / (a.harmonic_se * a.harmonic_se);
  }
  return chi2;
}

}  // namespace

double StopDistanceStart(std::span<const RecordAnalysis> analyses, ResponseKind kind, const ActuatorModel& start,
                         const ContactEstimate& contact, int orders) {
  const double lo = contact.largest_clear_amplitude_m, hi = contact.smallest_contacting_amplitude_m;
  if (!(lo > 0) || !(hi > lo) || contact.records.empty()) return contact.stop_distance_m;
  std::vector<double> distances(kStopGridPoints), chi2(kStopGridPoints);
  for (int k = 0; k < kStopGridPoints; ++k)
    distances[k] = lo * std::pow(hi / lo, static_cast<double>(k) / (kStopGridPoints - 1));
  ParallelFor(distances.size(), [&](size_t k) {
    ActuatorModel m = start;
    if (contact.lower_stop)
      m.lower_stop_m = -distances[k];
    else
      m.upper_stop_m = distances[k];
    chi2[k] = ContactingChi2(analyses, contact.records, kind, m, orders);
  });
  const size_t best = static_cast<size_t>(std::min_element(chi2.begin(), chi2.end()) - chi2.begin());
  return std::isfinite(chi2[best]) ? distances[best] : contact.stop_distance_m;
}

}  // namespace strokelab::fit_internal
