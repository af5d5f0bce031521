// What the missing physics changes for the control loop: the saturation maps (steady states, the
// saturation threshold per frequency, the jump intervals per amplitude; sweep.h) of the base model
// and of the diagnosed model (Diagnosis::model) over the campaign's range, and how far the threshold
// moved between them. Computed here, in the report layer, for the diagnosis report: the core
// diagnosis stays free of sweeps and pictures.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "strokelab/diagnose/broadband_diagnose.h"
#include "strokelab/diagnose/diagnose.h"
#include "strokelab/sweep/sweep.h"

namespace strokelab::report {

struct DiagnosisMaps {
  // The grid both models are swept on: the records' estimated drive frequencies (geometric, as the
  // map's log axis) and amplitudes (linear), end to end, at DiagnoseOptions::map_*_points.
  GridAxis frequency_hz, amplitude_v;
  // Each model's sweep when it ran to the end; else the note says why not (cut off by the time
  // budget, the grid rejected). A row or column whose numerics fail leaves a hole in its map, listed
  // in SweepResult::failures. Nothing missing: the diagnosed model is the base model and `diagnosed`
  // is not swept again (same_model).
  std::optional<SweepResult> base, diagnosed;
  std::string base_note, diagnosed_note;
  bool same_model = false;
  std::string note;  // why there are no maps at all ("" when they were attempted)
  double seconds = 0.0;
};

// Sweeps the base and the diagnosed model of `diagnosis` on the grid of `options`
// (map_frequency_points x map_amplitude_points; 0 in either: no maps, said in `note`) on one thread
// per core, with the thresholds and jump intervals. The sweeps share what is left of the diagnosis's
// time budget (options.max_seconds - diagnosis.seconds): a sweep still running when it is spent is
// cut off at its next row or column and reported in its note. The two sweeps are the diagnosis's last
// two progress stages (options.progress, diagnose.h), with their grid points as they pass.
DiagnosisMaps SweepDiagnosisMaps(const Diagnosis& diagnosis, const DiagnoseOptions& options);

// The same for a broadband diagnosis (diagnose/broadband_diagnose.h), base model its base fit's: the
// frequencies span the records' drive band (where a drive's power is within 20 dB of its largest,
// BroadbandFrf), the sine amplitudes run from the quietest record's rms drive times sqrt 2 (a sine of
// that rms) to the largest peak of any record's drive.
DiagnosisMaps SweepBroadbandDiagnosisMaps(const BroadbandDiagnosis& diagnosis, const Campaign& campaign,
                                          const DiagnoseOptions& options);

// Where the saturation threshold moved, at one grid frequency [V]: base and diagnosed model's
// grazing amplitude (the non-contacting response first touches the stop) and lowest amplitude with a
// stable contacting response (SaturationThreshold). NaN where a model has none.
struct ThresholdShift {
  double frequency_hz = 0.0;
  double base_grazing_v = 0.0, diagnosed_grazing_v = 0.0;
  double base_lowest_contact_v = 0.0, diagnosed_lowest_contact_v = 0.0;
  double GrazingShiftV() const { return diagnosed_grazing_v - base_grazing_v; }
  double GrazingShiftPercent() const { return 100.0 * GrazingShiftV() / base_grazing_v; }
  double LowestContactShiftV() const { return diagnosed_lowest_contact_v - base_lowest_contact_v; }
  double LowestContactShiftPercent() const { return 100.0 * LowestContactShiftV() / base_lowest_contact_v; }
};

// Per frequency of `base`'s thresholds, the diagnosed model's at the same frequency (NaN where it
// has no threshold at that frequency).
std::vector<ThresholdShift> ThresholdShifts(const SweepResult& base, const SweepResult& diagnosed);

// One or two sentences: the largest move of the grazing threshold (where, from what to what, in V
// and %) and the mean move in %, and at how many frequencies only one of the models reaches the stop.
std::string ThresholdShiftSummary(const std::vector<ThresholdShift>& shifts);

}  // namespace strokelab::report
