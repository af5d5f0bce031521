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

ResponseKind ParseResponseKind(const std::string& text) {
  if (text == "force") return ResponseKind::kForce;
  if (text == "acceleration") return ResponseKind::kAcceleration;
  if (text == "velocity") return ResponseKind::kVelocity;
  if (text == "displacement") return ResponseKind::kDisplacement;
  throw InputError("channels", "unknown response channel '" + text +
                                   "' (known: force, acceleration, velocity, displacement)");
}

}  // namespace strokelab
