#include "lidartag/sim/truth.hpp"

#include <Eigen/Geometry>
#include <fstream>
#include <nlohmann/json.hpp>

namespace lidartag::sim {
namespace {

nlohmann::json vec(const Eigen::Vector3d& v) {
  return {v.x(), v.y(), v.z()};
}
nlohmann::json vec4(const Eigen::Vector4d& v) {
  return {v[0], v[1], v[2], v[3]};
}

}  // namespace

Eigen::Vector4d quaternion_wxyz(const Eigen::Matrix3d& rotation) {
  Eigen::Quaterniond q(rotation);
  q.normalize();
  if (q.w() < 0.0) q.coeffs() *= -1.0;
  return {q.w(), q.x(), q.y(), q.z()};
}

nlohmann::json truth_to_json(const Truth& truth) {
  nlohmann::json rotations = nlohmann::json::array();
  for (const RotationTruth& r : truth.rotations) {
    nlohmann::json tags = nlohmann::json::array();
    for (const TagTruth& t : r.tags) {
      nlohmann::json corners = nlohmann::json::array();
      for (const auto& c : t.corners) corners.push_back(vec(c));
      tags.push_back({{"family", t.family},
                      {"id", t.id},
                      {"size", t.size},
                      {"position", vec(t.position)},
                      {"orientation", vec4(t.orientation)},
                      {"corners", corners},
                      {"returns", t.returns}});
    }
    rotations.push_back(
        {{"index", r.index},
         // The number the driver gives it (lidartag detect, dump, the daemon, Python): the run
         // starts with a partial rotation, number 0.
         {"sequence", r.index + 1},
         {"stamp", static_cast<double>(r.stamp_ns) * 1e-9},
         {"stamp_ns", r.stamp_ns},
         {"sensor",
          {{"position", vec(r.sensor_position)}, {"orientation", vec4(r.sensor_orientation)}}},
         {"tags", tags}});
  }
  return {{"model", truth.model},
          {"return_mode", truth.return_mode},
          {"rpm", truth.rpm},
          {"seed", truth.seed},
          {"rotations", rotations}};
}

void write_truth(const Truth& truth, const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw OutputError("cannot write truth file '" + path + "'");
  out << truth_to_json(truth).dump(2) << '\n';
  if (!out) throw OutputError("error writing truth file '" + path + "'");
}

}  // namespace lidartag::sim
