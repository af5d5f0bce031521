// What `strokelab sweep` (and the service) make of a SweepResult: the --json object, the --out folder (CSV tables,
// SVG pictures, summary.txt) and the text summary. Pure functions of the result and the model, so
// they are tested on synthetic results without running a sweep.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "strokelab/model/model.h"
#include "strokelab/sweep/sweep.h"

namespace strokelab::report {

// One JSON object: points, saturation_threshold, jump, grid, model, wall_time_s, points_per_second.
// A point's period is a number, or "aperiodic" when SweepPoint::period == 0. Non-finite numbers are
// written as null.
nlohmann::json SweepToJson(const SweepResult& result, const ActuatorModel& model);

// The human summary: grid, wall time, counts of steady states by branch and period, the saturation
// thresholds at about ten frequencies (and the lowest grazing amplitude), the jump intervals.
std::string SweepSummaryText(const SweepResult& result);

// The colour of the saturation maps: peak blocked force over first-harmonic force amplitude,
// peak_force_n / first_harmonic_force_n (dimensionless). 1 for a sinusoidal response at any
// frequency, and it grows with the impact spikes, so the map shows the saturation itself rather
// than the resonance ridge that dominates |H| (which the FRF pictures show). NaN if undefined.
double SpikeFactor(const SweepPoint& point);

// How a saturation map is drawn: its title (empty: "Stroke saturation, up-sweep branch: ...") and
// the colour bar's SpikeFactor range (NaN: from the data), fixed to draw maps side by side on one
// scale.
struct SaturationMapStyle {
  std::string title;
  double spike_factor_min = 0.0 / 0.0, spike_factor_max = 0.0 / 0.0;
};

// The saturation map of one branch (see WriteSweepFolder) and the |H| family (paper Fig. 10) as SVG.
std::string SaturationMapSvg(const SweepResult& result, Branch branch, const SaturationMapStyle& style = {});
std::string FrfMagnitudeSvg(const SweepResult& result, Branch branch);

// The files WriteSweepFolder writes, in order.
const std::vector<std::string>& SweepFolderFiles();

// Writes SweepFolderFiles() into `dir` (created if missing):
//   model.json                the model swept (ModelToJson)
//   points.csv                one row per steady state (grid point x branch); period empty: aperiodic
//   saturation_threshold.csv  per grid frequency: grazing and lowest contacting amplitude [V]
//   jump.csv                  per bistable interval: amplitude, frequency bounds, what bounds it
//   saturation_map.svg        SpikeFactor of the up branch over (frequency, amplitude), with the
//                             grazing and lowest-contact curves and the jump intervals on top
//   saturation_map_down.svg   the same for the down branch
//   frf_up.svg, frf_down.svg  |H| against frequency, one line per amplitude coloured by amplitude
//                             with a colour bar (paper Fig. 10), log frequency axis; dots: unstable
//                             orbits; the sweep's jumps marked (up: at the bistable interval's upper
//                             end, down: at its lower end)
//   frf_phase.svg             arg H [rad], up branch solid, down branch dashed
//   summary.txt               SweepSummaryText
// Throws std::runtime_error if a file cannot be written.
void WriteSweepFolder(const SweepResult& result, const ActuatorModel& model, const std::filesystem::path& dir);

}  // namespace strokelab::report
