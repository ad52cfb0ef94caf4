// A sensor model as users name it (the tools' --model, Python's model=): a Velodyne model
// ("vlp32c", "VLP-32C", "ultra-puck") or an Ouster model name ("os1-128", any case). One parser for
// every front end, so that each accepts the same names and the same beam tables stand behind them.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "lidartag/driver/velodyne/sensor_model.hpp"

namespace lidartag::driver {

struct ModelName {
  std::optional<velodyne::Model> velodyne;  // set for a Velodyne model
  std::string ouster;                       // else an Ouster model name, lower case ("os1-128")
};

// The model `name` names (any case); nullopt for a name of neither vendor.
std::optional<ModelName> model_from_name(std::string_view name);

// Every accepted name, for messages: "vlp16, puck-hires, ...; Ouster: os0, os1, os2 with -16,
// -32, -64 or -128 beams".
std::string model_names();

// What places the rings of a cloud without a ring field (detector::CloudScanOptions): the beam
// elevations of `model`, degrees (a Velodyne model's laser table; an Ouster model's nominal beam
// altitudes, ouster/models.hpp: evenly spaced for OS1, a real unit's differ by tenths of a
// degree), else `rings` beams to estimate from the cloud; an Ouster name without a nominal table
// ("os1-32") gives its beam count when `rings` is 0.
struct RingSource {
  std::vector<double> elevations_deg;
  int rings = 0;
};
RingSource ring_source(const std::optional<ModelName>& model, int rings);

}  // namespace lidartag::driver
