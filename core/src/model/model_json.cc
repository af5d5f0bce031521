#include "strokelab/model/model_json.h"

#include <cmath>
#include <nlohmann/json.hpp>

#include "strokelab/base/json_number.h"

namespace strokelab {

ActuatorModel ModelFromJson(const nlohmann::json& json, const std::string& pointer) {
  if (json.is_string()) return PresetModel(json.get<std::string>());
  if (!json.is_object())
    throw InputError(pointer, "expected a preset name or an object of model parameters");
  ActuatorModel model = PaperModel();
  if (auto it = json.find("preset"); it != json.end()) {
    if (!it->is_string()) throw InputError(pointer + "/preset", "expected a preset name");
    try {
      model = PresetModel(it->get<std::string>());
    } catch (const InputError& e) {
      throw InputError(pointer + "/preset", e.bare_message());
    }
  }
  for (const auto& [key, value] : json.items()) {
    const std::string field = pointer + "/" + key;
    if (key == "preset") continue;
    if (key == "contact_law") {
      if (!value.is_string()) throw InputError(field, "expected \"linear\" or \"hertzian\"");
      try {
        model.contact_law = ParseContactLaw(value.get<std::string>());
      } catch (const InputError& e) {
        throw InputError(field, e.bare_message());
      }
      continue;
    }
    const ParameterInfo* info = nullptr;
    try {
      info = &FindParameter(key);
    } catch (const InputError& e) {
      throw InputError(field, e.bare_message());
    }
    if (value.is_null()) {
      // null: the term is absent (no stop, no amplifier limit).
      const std::string name = info->json_name;
      if (name == "lower_stop_m") model.lower_stop_m = ActuatorModel::kNoLowerStop;
      else if (name == "upper_stop_m") model.upper_stop_m = ActuatorModel::kNoUpperStop;
      else if (name == "amplifier_limit_v") model.amplifier_limit_v = ActuatorModel::kNoLimit;
      else throw InputError(field, "must be a number (null only means 'absent' for stops and limits)");
      continue;
    }
    if (!value.is_number()) throw InputError(field, "expected a number");
    model.*(info->field) = value.get<double>();
  }
  try {
    Validate(model);
  } catch (const InputError& e) {
    const ParameterInfo& info = FindParameter(e.field());
    throw InputError(pointer + "/" + info.json_name, e.bare_message());
  }
  return model;
}

nlohmann::json ModelToJson(const ActuatorModel& model) {
  nlohmann::json json = nlohmann::json::object();
  for (const ParameterInfo& info : Parameters()) {
    const double value = model.*(info.field);
    json[info.json_name] = JsonNumber(value);
  }
  json["contact_law"] = ToString(model.contact_law);
  return json;
}

}  // namespace strokelab
