// The steady-state figures of one simulated record, taken over its last whole second
// (whole drive periods): what `strokelab simulate --json` prints.
#pragma once

#include "strokelab/model/dynamics.h"
#include "strokelab/engines/engine.h"
#include "strokelab/signal/signal.h"

namespace strokelab {

struct RecordSummary {
  SampleWindow window;                  // the analysed samples
  double min_displacement_m = 0.0;
  double max_displacement_m = 0.0;
  size_t contacts = 0;                  // contacts that start in the window
  double mean_contact_ms = 0.0;         // mean duration of the closed contacts that start in it (NaN: none)
  double contact_time_rsd = 0.0;        // paper Eq. 6, corrected (NaN below 2 contacts)
  double peak_force_n = 0.0;            // max |f|
  double first_harmonic_force_n = 0.0;  // |C_1(f)|
  double first_harmonic_phase_rad = 0.0;// arg(C_1(f) / C_1(v_in)), the phase of H
};

RecordSummary Summarize(const Record& record, const SineDrive& drive, double span_s = 1.0);

}  // namespace strokelab
