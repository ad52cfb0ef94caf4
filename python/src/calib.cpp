// Camera-LiDAR calibration from Python (issue 30 item 4): camera models and intrinsics files, the
// extrinsic solver on corner arrays, and AprilTag 3 on images. The arrays are checked here (shape,
// finiteness) so that wrong input is a ValueError, never undefined behaviour; the wrapper in
// python/lidartag/__init__.py broadcasts the optional arguments and builds the result object from
// calibration_json(), so Python sees exactly the keys of `lidartag calibrate --json`.
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "bindings.hpp"
#include "lidartag/calib/calibration_report.hpp"
#include "lidartag/calib/camera_model.hpp"
#include "lidartag/calib/correspondence.hpp"
#include "lidartag/calib/extrinsic_solver.hpp"
#include "lidartag/calib/image_io.hpp"
#include "lidartag/calib/image_tags.hpp"
#include "lidartag/calib/intrinsics_file.hpp"
#include "lidartag/detector/tag_family.hpp"

namespace lidartag::python {
namespace {

using calib::CameraModel;
using calib::Distortion;
using Doubles = py::array_t<double, py::array::c_style | py::array::forcecast>;

std::string distortion_name(Distortion d) {
  switch (d) {
    case Distortion::kPlumbBob:
      return "plumb_bob";
    case Distortion::kEquidistant:
      return "equidistant";
    case Distortion::kNone:
      break;
  }
  return "none";
}

// The coefficients a model uses (plumb_bob k1 k2 p1 p2 k3, equidistant k1..k4, none none).
std::size_t coefficient_count(Distortion d) {
  return d == Distortion::kPlumbBob ? 5 : d == Distortion::kEquidistant ? 4 : 0;
}

CameraModel make_camera(int width, int height, double fx, double fy, double cx, double cy,
                        const std::string& distortion, const std::vector<double>& coefficients,
                        double skew) {
  CameraModel c;
  c.width = width;
  c.height = height;
  c.fx = fx;
  c.fy = fy;
  c.cx = cx;
  c.cy = cy;
  c.skew = skew;
  if (distortion == "none")
    c.distortion = Distortion::kNone;
  else if (distortion == "plumb_bob")
    c.distortion = Distortion::kPlumbBob;
  else if (distortion == "equidistant" || distortion == "fisheye")
    c.distortion = Distortion::kEquidistant;
  else
    throw py::value_error(
        "CameraModel: distortion must be 'none', 'plumb_bob' or 'equidistant', "
        "not '" +
        distortion + "'");
  const std::size_t n = coefficient_count(c.distortion);
  // "none" takes no coefficients or all zeros; the others exactly theirs.
  bool zeros = true;
  for (double v : coefficients) zeros = zeros && v == 0.0;
  if (coefficients.size() != n && !(n == 0 && zeros))
    throw py::value_error("CameraModel: distortion '" + distortion + "' takes " +
                          std::to_string(n) + " coefficients, got " +
                          std::to_string(coefficients.size()));
  for (std::size_t i = 0; i < n; ++i) c.d[i] = coefficients[i];
  try {
    c.check();
  } catch (const calib::CameraModelError& e) {
    throw py::value_error(std::string("CameraModel: ") + e.what());
  }
  return c;
}

// Pixels of points (N x 3, or one point of 3), camera optical frame: N x 2 (or 2), NaN where the
// model has no pixel (behind the camera, outside the lens's field of view, non-finite input).
py::array_t<double> project(const CameraModel& c, const Doubles& points) {
  const bool single = points.ndim() == 1;
  if (!(single && points.shape(0) == 3) && !(points.ndim() == 2 && points.shape(1) == 3))
    throw py::value_error("project: points must be shaped (N, 3) or (3,)");
  const py::ssize_t n = single ? 1 : points.shape(0);
  py::array_t<double> out(single ? std::vector<py::ssize_t>{2} : std::vector<py::ssize_t>{n, 2});
  const double* in = points.data();
  double* o = out.mutable_data();
  for (py::ssize_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p(in[3 * i], in[3 * i + 1], in[3 * i + 2]);
    const std::optional<Eigen::Vector2d> px =
        p.allFinite() ? c.project(p) : std::optional<Eigen::Vector2d>{};
    o[2 * i] = px ? px->x() : std::nan("");
    o[2 * i + 1] = px ? px->y() : std::nan("");
  }
  return out;
}

void require_shape(const Doubles& a, std::vector<py::ssize_t> shape, const std::string& what) {
  bool ok = a.ndim() == static_cast<py::ssize_t>(shape.size());
  for (std::size_t i = 0; ok && i < shape.size(); ++i)
    ok = a.shape(static_cast<py::ssize_t>(i)) == shape[i];
  if (!ok) throw py::value_error("calibrate: " + what + " has the wrong shape");
  const double* d = a.data();
  for (py::ssize_t i = 0; i < a.size(); ++i)
    if (!std::isfinite(d[i])) throw py::value_error("calibrate: " + what + " is not finite");
}

// The solver on checked arrays: image (P, 4, 2) px, lidar (P, 4, 3) m, sigma_px (P), lidar_cov
// (P, 12, 12) m^2, labels (P). Returns calibration_json() as text.
std::string calibrate(const CameraModel& camera, const Doubles& image, const Doubles& lidar,
                      const Doubles& sigma_px, const Doubles& lidar_cov,
                      const std::vector<std::string>& labels, bool held_out,
                      const std::string& lidar_frame, const std::string& camera_frame) {
  const py::ssize_t n = image.ndim() == 3 ? image.shape(0) : 0;
  if (n < 1) throw py::value_error("calibrate: image_corners must be shaped (P, 4, 2), P >= 1");
  require_shape(image, {n, 4, 2}, "image_corners (P, 4, 2)");
  require_shape(lidar, {n, 4, 3}, "lidar_corners (P, 4, 3)");
  require_shape(sigma_px, {n}, "sigma_px (P,)");
  require_shape(lidar_cov, {n, 12, 12}, "lidar covariance (P, 12, 12)");
  if (labels.size() != static_cast<std::size_t>(n))
    throw py::value_error("calibrate: labels: one per pose");
  std::vector<calib::TagPose> poses(static_cast<std::size_t>(n));
  for (py::ssize_t i = 0; i < n; ++i) {
    calib::TagPose& p = poses[static_cast<std::size_t>(i)];
    p.label = labels[static_cast<std::size_t>(i)];
    p.sigma_px = sigma_px.at(i);
    for (py::ssize_t k = 0; k < 4; ++k) {
      p.pixels[static_cast<std::size_t>(k)] = {image.at(i, k, 0), image.at(i, k, 1)};
      p.lidar.corners[static_cast<std::size_t>(k)] = {lidar.at(i, k, 0), lidar.at(i, k, 1),
                                                      lidar.at(i, k, 2)};
    }
    for (py::ssize_t r = 0; r < 12; ++r)
      for (py::ssize_t c = 0; c < 12; ++c) p.lidar.corner_cov(r, c) = lidar_cov.at(i, r, c);
  }
  calib::SolverOptions options;
  options.held_out = held_out;
  calib::CalibrationResult result;
  {
    py::gil_scoped_release release;
    result = calib::solve_extrinsic(camera, poses, options);
  }
  return calib::calibration_json(result, {lidar_frame, camera_frame}).dump();
}

// A tag known only by its four corners (P x 4 x 3 array, pose i): its centre, its frame (x the
// normal, y right, z up: Detection::corners' convention) and its size from the corners, as the
// LidarTag the detector's pose would give (a family is needed only to turn the black square's
// side into a marker size; any family gives the same square).
calib::LidarTag tag_from_corners(const Doubles& corners, py::ssize_t i) {
  calib::LidarTag t;
  t.family = "tag36h11";
  const tags::TagFamily& family = tags::builtin_family(t.family);
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (py::ssize_t k = 0; k < 4; ++k) {
    Eigen::Vector3d& c = t.corners[static_cast<std::size_t>(k)];
    c = {corners.at(i, k, 0), corners.at(i, k, 1), corners.at(i, k, 2)};
    centre += c / 4;
  }
  const auto& c = t.corners;
  const Eigen::Vector3d y = ((c[1] - c[0]) + (c[2] - c[3])).normalized();
  Eigen::Vector3d z = (c[3] - c[0]) + (c[2] - c[1]);
  z = (z - z.dot(y) * y).normalized();
  Eigen::Matrix3d r;
  r << y.cross(z), y, z;
  const double side =
      ((c[1] - c[0]).norm() + (c[2] - c[3]).norm() + (c[3] - c[0]).norm() + (c[2] - c[1]).norm()) /
      4;
  if (!(side > 0) || !r.allFinite())
    throw py::value_error("lidar_corners of pose " + std::to_string(i) +
                          " do not make a square (corners that coincide)");
  t.position = centre;
  t.orientation = Eigen::Quaterniond(r);
  t.size_m = side / 2 / calib::black_half_side(family, 1.0);
  t.corner_cov.setZero();
  return t;
}

py::array_t<double> covariances(const std::vector<Eigen::Matrix<double, 12, 12>>& covs) {
  py::array_t<double> out(std::vector<py::ssize_t>{static_cast<py::ssize_t>(covs.size()), 12, 12});
  for (std::size_t i = 0; i < covs.size(); ++i)
    for (py::ssize_t r = 0; r < 12; ++r)
      for (py::ssize_t col = 0; col < 12; ++col)
        out.mutable_at(static_cast<py::ssize_t>(i), r, col) = covs[i](r, col);
  return out;
}

void require_corners(const Doubles& corners, const std::string& what) {
  const py::ssize_t n = corners.ndim() == 3 ? corners.shape(0) : 0;
  if (n < 1) throw py::value_error(what + ": lidar_corners must be shaped (P, 4, 3), P >= 1");
  bool ok = corners.shape(1) == 4 && corners.shape(2) == 3;
  const double* d = corners.data();
  for (py::ssize_t i = 0; ok && i < corners.size(); ++i) ok = std::isfinite(d[i]);
  if (!ok) throw py::value_error(what + ": lidar_corners must be finite and shaped (P, 4, 3)");
}

// calib::add_ring_spacing_uncertainty's term for each pose (P x 12 x 12, m^2): the tag of pose i
// (lidar_corners[i]) under the rings of ring_elevations[i] (radians).
py::array_t<double> ring_spacing_covariance(const Doubles& corners,
                                            const std::vector<std::vector<double>>& elevations) {
  require_corners(corners, "ring_spacing_covariance");
  const py::ssize_t n = corners.shape(0);
  if (elevations.size() != static_cast<std::size_t>(n))
    throw py::value_error("ring_spacing_covariance: " + std::to_string(elevations.size()) +
                          " ring elevation lists for " + std::to_string(n) + " poses");
  std::vector<Eigen::Matrix<double, 12, 12>> out;
  for (py::ssize_t i = 0; i < n; ++i) {
    const auto& el = elevations[static_cast<std::size_t>(i)];
    for (double e : el)
      if (!std::isfinite(e) || std::abs(e) > std::numbers::pi / 2)
        throw py::value_error(
            "ring_spacing_covariance: ring elevations are radians in [-pi/2, "
            "pi/2]");
    calib::LidarTag t = tag_from_corners(corners, i);
    calib::add_ring_spacing_uncertainty(t, tags::builtin_family(t.family), el);
    out.push_back(t.corner_cov);
  }
  return covariances(out);
}

// The corners' covariance `lidartag calibrate` gives one rotation's detection
// (calib::lidar_tag_from_detection with LidarCornerNoise), for each pose (P x 12 x 12, m^2).
py::array_t<double> detection_covariance(const Doubles& corners, double position_sigma_m,
                                         double angle_sigma_deg, double floor_m) {
  require_corners(corners, "detection_covariance");
  for (double v : {position_sigma_m, angle_sigma_deg, floor_m})
    if (!std::isfinite(v) || v < 0)
      throw py::value_error("detection_covariance: sigmas must be finite and not negative");
  std::vector<Eigen::Matrix<double, 12, 12>> out;
  for (py::ssize_t i = 0; i < corners.shape(0); ++i) {
    calib::LidarTag t = tag_from_corners(corners, i);
    t.corner_cov = calib::pose_corner_covariance(
        t, Eigen::Matrix3d::Identity() * position_sigma_m * position_sigma_m,
        angle_sigma_deg * std::numbers::pi / 180);
    t.corner_cov.diagonal().array() += floor_m * floor_m;
    out.push_back(t.corner_cov);
  }
  return covariances(out);
}

py::dict image_tag_dict(const calib::ImageTag& t) {
  py::dict d;
  d["family"] = t.family;
  d["id"] = t.id;
  d["hamming"] = t.hamming;
  d["decision_margin"] = t.decision_margin;
  py::array_t<double> corners(std::vector<py::ssize_t>{4, 2});
  for (py::ssize_t k = 0; k < 4; ++k) {
    corners.mutable_at(k, 0) = t.corners[static_cast<std::size_t>(k)].x();
    corners.mutable_at(k, 1) = t.corners[static_cast<std::size_t>(k)].y();
  }
  d["corners"] = corners;
  py::array_t<double> center(2);
  center.mutable_at(0) = t.center.x();
  center.mutable_at(1) = t.center.y();
  d["center"] = center;
  return d;
}

// AprilTag 3 on a grey image: a file (`path` non-empty) or a (H, W) uint8 array.
py::list detect_image_tags(const std::string& path,
                           const std::optional<py::array_t<uint8_t, py::array::c_style>>& pixels,
                           const std::vector<std::string>& families,
                           const std::optional<CameraModel>& camera, double decimate,
                           double min_decision_margin) {
  calib::GrayImage image;
  if (!path.empty()) {
    image = calib::read_gray(path);
  } else {
    if (!pixels || pixels->ndim() != 2)
      throw py::value_error("detect_image_tags: image must be a path or a (H, W) uint8 array");
    image.width = static_cast<int>(pixels->shape(1));
    image.height = static_cast<int>(pixels->shape(0));
    image.pixels.assign(pixels->data(), pixels->data() + pixels->size());
  }
  calib::ImageTagOptions options;
  options.families = families;
  options.decimate = decimate;
  options.min_decision_margin = min_decision_margin;
  std::vector<calib::ImageTag> tags;
  {
    py::gil_scoped_release release;
    calib::ImageTagDetector detector(options);
    tags = camera ? detector.detect(image, *camera) : detector.detect(image);
  }
  py::list out;
  for (const calib::ImageTag& t : tags) out.append(image_tag_dict(t));
  return out;
}

// A PNG or JPEG as a (H, W) uint8 grey array (row 0 the top).
py::array_t<uint8_t> read_gray_image(const std::string& path) {
  const calib::GrayImage image = calib::read_gray(path);
  py::array_t<uint8_t> out(std::vector<py::ssize_t>{image.height, image.width});
  std::copy(image.pixels.begin(), image.pixels.end(), out.mutable_data());
  return out;
}

}  // namespace

void bind_calib(py::module_& m) {
  py::class_<CameraModel>(m, "CameraModel",
                          "A camera's intrinsics (pixel (0, 0) the centre of the top-left pixel, "
                          "as ROS camera_info and OpenCV)")
      .def(py::init(&make_camera), py::arg("width"), py::arg("height"), py::arg("fx"),
           py::arg("fy"), py::arg("cx"), py::arg("cy"), py::arg("distortion") = "none",
           py::arg("coefficients") = std::vector<double>{}, py::arg("skew") = 0.0,
           "distortion: 'none', 'plumb_bob' (k1 k2 p1 p2 k3) or 'equidistant' (k1 k2 k3 k4). "
           "Raises ValueError for a camera that is not one (size, focal lengths, principal "
           "point, coefficients).")
      .def_readonly("width", &CameraModel::width)
      .def_readonly("height", &CameraModel::height)
      .def_readonly("fx", &CameraModel::fx)
      .def_readonly("fy", &CameraModel::fy)
      .def_readonly("cx", &CameraModel::cx)
      .def_readonly("cy", &CameraModel::cy)
      .def_readonly("skew", &CameraModel::skew)
      .def_property_readonly("distortion",
                             [](const CameraModel& c) { return distortion_name(c.distortion); })
      .def_property_readonly("coefficients",
                             [](const CameraModel& c) {
                               return std::vector<double>(
                                   c.d.begin(), c.d.begin() + static_cast<std::ptrdiff_t>(
                                                                  coefficient_count(c.distortion)));
                             })
      .def_property_readonly("K",
                             [](const CameraModel& c) {
                               py::array_t<double> k(std::vector<py::ssize_t>{3, 3});
                               const std::array<double, 9> v = {c.fx, c.skew, c.cx, 0, c.fy,
                                                                c.cy, 0,      0,    1};
                               std::copy(v.begin(), v.end(), k.mutable_data());
                               return k;
                             })
      .def("project", &project, py::arg("points"),
           "Pixels (N, 2) of points (N, 3) in the camera's optical frame (x right, y down, z "
           "forward), metres; NaN where there is none (behind the camera, outside the lens's "
           "field of view). Pixels outside the image are returned as they are.")
      .def("__repr__", [](const CameraModel& c) {
        return "<lidartag.CameraModel " + std::to_string(c.width) + "x" + std::to_string(c.height) +
               " " + distortion_name(c.distortion) + ">";
      });
  // Not a ValueError: the file is wrong, not the call.
  py::register_exception<calib::IntrinsicsFileError>(m, "IntrinsicsError", m.attr("Error").ptr());
  py::register_exception<calib::ImageError>(m, "ImageError", m.attr("Error").ptr());
  // Options out of range, an unknown family: also a ValueError.
  py::register_exception<calib::ImageTagError>(
      m, "ImageTagError", py::make_tuple(m.attr("Error"), py::handle(PyExc_ValueError)));
  // lidartag.CalibrationError is the Velodyne calibration file's (errors.cpp).
  py::register_exception<calib::CalibrationError>(m, "ExtrinsicError", m.attr("Error").ptr());
  m.def("_load_intrinsics", &calib::load_intrinsics, py::arg("path"));
  m.def("_calibrate", &calibrate);
  m.def("_ring_spacing_covariance", &ring_spacing_covariance, py::arg("lidar_corners"),
        py::arg("ring_elevations"));
  m.def("_detection_covariance", &detection_covariance, py::arg("lidar_corners"),
        py::arg("position_sigma_m"), py::arg("angle_sigma_deg"), py::arg("floor_m"));
  m.def(
      "_ring_elevations",
      [](const Rotation& r) {
        const std::vector<double> el = calib::ring_elevations_rad(r.scan);
        return py::array_t<double>(static_cast<py::ssize_t>(el.size()), el.data());
      },
      py::arg("rotation"));
  m.def("_detect_image_tags", &detect_image_tags);
  m.def("_read_image", &read_gray_image, py::arg("path"),
        "A PNG or JPEG file as a (H, W) uint8 grey array, row 0 the top (colour converted by "
        "libpng / libjpeg). Raises ImageError for an unreadable, unknown or corrupt file.");
}

}  // namespace lidartag::python
