#include "lidartag/driver/sources/model_name.hpp"

#include <algorithm>
#include <cctype>
#include <string>

#include "lidartag/driver/ouster/models.hpp"

namespace lidartag::driver {

std::optional<ModelName> model_from_name(std::string_view name) {
  std::string n(name);
  std::transform(n.begin(), n.end(), n.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (const auto m = velodyne::model_from_name(n)) return ModelName{m, {}};
  if (ouster::is_model_name(n)) return ModelName{std::nullopt, n};
  return std::nullopt;
}

std::string model_names() {
  return velodyne::model_names() + "; Ouster: os0, os1, os2 with -16, -32, -64 or -128 beams";
}

RingSource ring_source(const std::optional<ModelName>& model, int rings) {
  RingSource r;
  r.rings = rings;
  if (!model) return r;
  if (model->velodyne) {
    r.elevations_deg = velodyne::beam_elevations_deg(model->velodyne);
  } else if (const auto m = ouster::model_from_name(model->ouster)) {
    r.elevations_deg = ouster::nominal_beam_altitudes_deg(*m);
  } else if (r.rings <= 0) {
    r.rings = std::stoi(model->ouster.substr(model->ouster.find('-') + 1));  // "os1-32": 32
  }
  return r;
}

}  // namespace lidartag::driver
