// Models as JSON: a preset name ("paper"), or an object {"preset": "paper", "k3": 4e7, ...} whose
// keys are the parameter keys or JSON names of model.h. Infinite values (no stop, no limit) are
// written as null. Errors name the JSON pointer of the offending field.
#pragma once

#include <nlohmann/json_fwd.hpp>
#include <string>

#include "strokelab/model/model.h"

namespace strokelab {

// `pointer` is the JSON pointer of `json` inside its document, used in error messages.
ActuatorModel ModelFromJson(const nlohmann::json& json, const std::string& pointer = "/model");
nlohmann::json ModelToJson(const ActuatorModel& model);

}  // namespace strokelab
