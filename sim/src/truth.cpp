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

std::string distortion_name(calib::Distortion d) {
  switch (d) {
    case calib::Distortion::kNone:
      return "none";
    case calib::Distortion::kPlumbBob:
      return "plumb_bob";
    case calib::Distortion::kEquidistant:
      return "equidistant";
  }
  return "none";
}

nlohmann::json camera_to_json(const CameraTruth& c) {
  const calib::CameraModel& m = c.model;
  nlohmann::json matrix = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) {
    nlohmann::json row = nlohmann::json::array();
    for (int k = 0; k < 4; ++k)
      row.push_back(r < 3 ? (k < 3 ? c.rotation(r, k) : c.translation[r]) : (k < 3 ? 0.0 : 1.0));
    matrix.push_back(row);
  }
  return {{"pixel_convention", "(0, 0) is the centre of the top-left pixel"},
          {"width", m.width},
          {"height", m.height},
          {"fx", m.fx},
          {"fy", m.fy},
          {"cx", m.cx},
          {"cy", m.cy},
          {"skew", m.skew},
          {"distortion_model", distortion_name(m.distortion)},
          {"distortion_coefficients", m.d},
          {"lidar_to_camera",
           {{"rotation_wxyz", vec4(quaternion_wxyz(c.rotation))},
            {"translation_m", vec(c.translation)},
            {"matrix", matrix}}}};
}

}  // namespace

CameraTruth camera_truth_from_json(const nlohmann::json& j) {
  CameraTruth c;
  try {
    calib::CameraModel& m = c.model;
    m.width = j.at("width").get<int>();
    m.height = j.at("height").get<int>();
    m.fx = j.at("fx").get<double>();
    m.fy = j.at("fy").get<double>();
    m.cx = j.at("cx").get<double>();
    m.cy = j.at("cy").get<double>();
    m.skew = j.at("skew").get<double>();
    const std::string d = j.at("distortion_model").get<std::string>();
    if (d == "none")
      m.distortion = calib::Distortion::kNone;
    else if (d == "plumb_bob")
      m.distortion = calib::Distortion::kPlumbBob;
    else if (d == "equidistant")
      m.distortion = calib::Distortion::kEquidistant;
    else
      throw TruthError("camera.distortion_model: unknown '" + d + "'");
    m.d = j.at("distortion_coefficients").get<std::array<double, 5>>();
    const auto& e = j.at("lidar_to_camera");
    const auto q = e.at("rotation_wxyz").get<std::array<double, 4>>();
    c.rotation = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
    const auto t = e.at("translation_m").get<std::array<double, 3>>();
    c.translation = Eigen::Vector3d(t[0], t[1], t[2]);
    m.check();
  } catch (const nlohmann::json::exception& e) {
    throw TruthError(std::string("camera: ") + e.what());
  } catch (const calib::CameraModelError& e) {
    throw TruthError(std::string("camera: ") + e.what());
  }
  return c;
}

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
      nlohmann::json tag = {{"family", t.family},
                            {"id", t.id},
                            {"size", t.size},
                            {"position", vec(t.position)},
                            {"orientation", vec4(t.orientation)},
                            {"corners", corners},
                            {"returns", t.returns}};
      if (truth.camera) {
        nlohmann::json px = nullptr;
        if (t.image_corners) {
          px = nlohmann::json::array();
          for (const auto& c : *t.image_corners) px.push_back({c.x(), c.y()});
        }
        tag["image_corners"] = px;
      }
      tags.push_back(tag);
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
  nlohmann::json out = {{"model", truth.model},
                        {"return_mode", truth.return_mode},
                        {"rpm", truth.rpm},
                        {"seed", truth.seed}};
  if (truth.camera) out["camera"] = camera_to_json(*truth.camera);
  out["rotations"] = rotations;
  return out;
}

void write_truth(const Truth& truth, const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw OutputError("cannot write truth file '" + path + "'");
  out << truth_to_json(truth).dump(2) << '\n';
  if (!out) throw OutputError("error writing truth file '" + path + "'");
}

}  // namespace lidartag::sim
