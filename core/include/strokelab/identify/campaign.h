// A measurement campaign in memory: stepped-sine (or broadband) records of drive voltage and one
// response channel, in physical units (shared/docs/recordings-format.md). Reading and writing the
// files is done outside core (clients/recordings); fitting and diagnosis work on these types.
#pragma once

#include <string>
#include <vector>

#include "strokelab/model/dynamics.h"

namespace strokelab {

// What the response channel measures (of the moving mass, or the blocked force).
enum class ResponseKind { kForce, kAcceleration, kVelocity, kDisplacement };
const char* ToString(ResponseKind kind);
const char* UnitOf(ResponseKind kind);  // of the response: "N", "m/s^2", "m/s", "m"
ResponseKind ParseResponseKind(const std::string& text);  // "force", ...; throws InputError("channels")
// The response of `kind` in physical units from the state and the blocked force f = m_p x'' at one
// instant: f, f / m_p, v or x.
double ResponseOf(ResponseKind kind, double mass_kg, const State& y, double force_n);

struct Recording {
  std::string name;                   // the file it came from, for messages
  double sample_rate_hz = 0.0;        // fs [Hz]; sample n is at t = n / fs
  std::vector<double> voltage_v;      // drive before the amplifier [V]
  std::vector<double> response;       // [N], [m/s^2], [m/s] or [m] per ResponseKind (sensitivity applied)
  bool broadband = false;             // noise/multisine/sweep: no nominal frequency
  double nominal_frequency_hz = 0.0;  // stepped sine: as the manifest says (the voltage channel is the truth)
  double nominal_amplitude_v = 0.0;
  size_t size() const { return voltage_v.size(); }
};

struct Campaign {
  std::string actuator;
  ResponseKind response = ResponseKind::kForce;
  // False when the sensitivity is only nominal: the response's absolute scale is unknown and only
  // ratios of model parameters are identifiable.
  bool absolute_scale = true;
  std::vector<Recording> records;
};

}  // namespace strokelab
