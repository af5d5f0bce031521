#include "strokelab/identify/campaign.h"

#include "strokelab/base/errors.h"

namespace strokelab {

const char* ToString(ResponseKind kind) {
  switch (kind) {
    case ResponseKind::kForce: return "force";
    case ResponseKind::kAcceleration: return "acceleration";
    case ResponseKind::kVelocity: return "velocity";
    case ResponseKind::kDisplacement: return "displacement";
  }
  return "?";
}

const char* UnitOf(ResponseKind kind) {
  switch (kind) {
    case ResponseKind::kForce: return "N";
    case ResponseKind::kAcceleration: return "m/s^2";
    case ResponseKind::kVelocity: return "m/s";
    case ResponseKind::kDisplacement: return "m";
  }
  return "";
}

double ResponseOf(ResponseKind kind, double mass_kg, const State& y, double force_n) {
  switch (kind) {
    case ResponseKind::kForce: return force_n;
    case ResponseKind::kAcceleration: return force_n / mass_kg;
    case ResponseKind::kVelocity: return y.v_m_per_s;
    case ResponseKind::kDisplacement: return y.x_m;
  }
  return 0.0;
}

ResponseKind ParseResponseKind(const std::string& text) {
  if (text == "force") return ResponseKind::kForce;
  if (text == "acceleration") return ResponseKind::kAcceleration;
  if (text == "velocity") return ResponseKind::kVelocity;
  if (text == "displacement") return ResponseKind::kDisplacement;
  throw InputError("channels", "unknown response channel '" + text +
                                   "' (known: force, acceleration, velocity, displacement)");
}

}  // namespace strokelab
