// The detector with the options of lidartagd's YAML (the daemon's own mapping,
// lidartag::daemon::parse_detector_config), its detections as Python objects with numpy poses.
#include "lidartag/detector/detector.hpp"

#include <pybind11/eigen.h>
#include <pybind11/stl.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "bindings.hpp"
#include "lidartag/daemon/config.hpp"

namespace lidartag::python {
namespace {

namespace det = lidartag::detector;

// A Python value (dict, list, str, number, bool, None, numpy array or scalar) as YAML.
YAML::Node to_yaml(py::handle h, const std::string& where) {
  if (h.is_none()) return YAML::Node(YAML::NodeType::Null);
  if (py::isinstance<py::bool_>(h)) return YAML::Node(h.cast<bool>());
  if (py::isinstance<py::str>(h)) return YAML::Node(h.cast<std::string>());
  if (py::isinstance<py::float_>(h)) return YAML::Node(h.cast<double>());
  if (py::isinstance<py::int_>(h)) return YAML::Node(h.cast<long long>());
  if (py::hasattr(h, "tolist") && !py::isinstance<py::dict>(h))  // numpy arrays and scalars
    return to_yaml(h.attr("tolist")(), where);
  if (py::isinstance<py::dict>(h)) {
    YAML::Node map(YAML::NodeType::Map);
    for (const auto& [key, value] : h.cast<py::dict>()) {
      if (!py::isinstance<py::str>(key))
        throw py::type_error(where + ": keys must be strings, not " +
                             std::string(py::str(key.get_type().attr("__name__"))));
      const std::string k = key.cast<std::string>();
      map[k] = to_yaml(value, where + "." + k);
    }
    return map;
  }
  if (py::isinstance<py::list>(h) || py::isinstance<py::tuple>(h)) {
    YAML::Node seq(YAML::NodeType::Sequence);
    for (const auto& item : h) seq.push_back(to_yaml(item, where + "[]"));
    return seq;
  }
  throw py::type_error(where + ": cannot be written as YAML: " +
                       std::string(py::str(h.get_type().attr("__name__"))));
}

// Options from a config: None (the YAML's defaults), a dict (a `detector:` section, or a whole
// configuration with a `detector` key), a file path or a YAML document.
det::DetectorOptions options_of(const py::object& config) {
  if (config.is_none()) return daemon::daemon_detector_defaults();
  const py::module_ os = py::module_::import("os");
  if (py::isinstance<py::dict>(config)) {
    YAML::Node root = to_yaml(config, "config");
    if (!root["detector"]) {
      YAML::Node whole(YAML::NodeType::Map);
      whole["detector"] = root;
      root = whole;
    }
    YAML::Emitter out;
    out << root;
    return daemon::parse_detector_config(out.c_str(), "config (dict)");
  }
  if (py::isinstance(config, os.attr("PathLike"))) {
    return daemon::load_detector_config(os.attr("fspath")(config).cast<std::string>());
  }
  if (py::isinstance<py::str>(config)) {
    const std::string text = config.cast<std::string>();
    if (os.attr("path").attr("isfile")(config).cast<bool>())
      return daemon::load_detector_config(text);
    return daemon::parse_detector_config(text, "config (YAML text)");
  }
  throw py::type_error("config: None, a dict, a path or a YAML string");
}

struct PyDetection {
  std::string family;
  int family_index = 0;
  int id = 0;
  double size_m = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector4d orientation{1, 0, 0, 0};  // w, x, y, z
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
  Eigen::Matrix<double, 4, 3, Eigen::RowMajor> corners =
      Eigen::Matrix<double, 4, 3, Eigen::RowMajor>::Zero();
  double score = 0, margin = 0, fit_cost = 0;
  int points = 0;
  double time_first_s = 0, time_center_s = 0, time_last_s = 0;
  double measured_size_m = -1;
  bool size_warning = false;
  std::string deskew = "none";
};

struct PyResult {
  std::vector<PyDetection> detections;
  int features = 0, clusters = 0;
  int deskewed_ego = 0, deskewed_model = 0, deskew_without_motion = 0;
  std::map<std::string, double> timing_ms;
  std::map<std::string, uint32_t> rejected;
  double total_ms = 0;
  std::vector<std::map<std::string, double>> diagnostics;
  std::vector<std::string> diagnostic_results;
  int64_t stamp_ns = 0;
  uint64_t sequence = 0;
};

PyDetection convert(const det::Detection& d) {
  PyDetection p;
  p.family = std::string(d.family);
  p.family_index = d.family_index;
  p.id = d.id;
  p.size_m = d.size_m;
  p.position = d.position;
  const Eigen::Quaterniond q = d.orientation.normalized();
  p.orientation = Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
  p.rotation = q.toRotationMatrix();
  p.pose.topLeftCorner<3, 3>() = p.rotation;
  p.pose.topRightCorner<3, 1>() = d.position;
  for (int c = 0; c < 4; ++c) p.corners.row(c) = d.corners[static_cast<size_t>(c)].transpose();
  p.score = d.score;
  p.margin = d.margin;
  p.points = d.points;
  p.fit_cost = d.fit_cost;
  p.time_first_s = d.time_first_s;
  p.time_center_s = d.time_center_s;
  p.time_last_s = d.time_last_s;
  p.measured_size_m = d.measured_size_m;
  p.size_warning = d.size_warning;
  p.deskew = std::string(det::deskew_source_name(d.deskew));
  return p;
}

// One detector; calls are serialised (a Detector is used by one thread at a time) and run
// without the GIL.
class PyDetector {
 public:
  explicit PyDetector(det::DetectorOptions options)
      : detector_(std::make_unique<det::Detector>(std::move(options))) {}

  PyResult detect(const Rotation& rotation) {
    PyResult out;
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(mutex_);
    detector_->detect(rotation.scan, result_);
    for (const auto& d : result_.detections) out.detections.push_back(convert(d));
    out.features = result_.features;
    out.clusters = result_.clusters;
    out.deskewed_ego = result_.deskewed_ego;
    out.deskewed_model = result_.deskewed_model;
    out.deskew_without_motion = result_.deskew_without_motion;
    for (int s = 0; s < det::kStageCount; ++s)
      out.timing_ms[std::string(det::stage_name(static_cast<det::Stage>(s)))] =
          result_.timing_ms[static_cast<size_t>(s)];
    for (int k = 1; k < det::kRejectionCount; ++k) {
      const auto reason = static_cast<det::Rejection>(k);
      if (result_.rejected[static_cast<size_t>(k)] == 0) continue;
      out.rejected[std::string(det::rejection_stage(reason)) + "/" +
                   std::string(det::rejection_name(reason))] =
          result_.rejected[static_cast<size_t>(k)];
    }
    out.total_ms = result_.total_ms();
    for (const auto& c : result_.diagnostics) {
      out.diagnostics.push_back({{"features", c.features},
                                 {"points", c.points},
                                 {"boundary_points", c.boundary_points},
                                 {"min_x", c.min_x},
                                 {"max_x", c.max_x},
                                 {"min_y", c.min_y},
                                 {"max_y", c.max_y},
                                 {"min_ring", c.min_ring},
                                 {"max_ring", c.max_ring},
                                 {"outlier_ratio", c.outlier_ratio},
                                 {"side_m", c.side_m},
                                 {"mean_cost_m", c.mean_cost_m},
                                 {"coverage", c.coverage},
                                 {"score", c.score},
                                 {"margin", c.margin}});
      out.diagnostic_results.push_back(std::string(det::rejection_stage(c.rejection)) + "/" +
                                       std::string(det::rejection_name(c.rejection)));
    }
    out.stamp_ns = rotation.scan.stamp_ns;
    out.sequence = rotation.scan.sequence;
    return out;
  }

  const det::DetectorOptions& options() const { return detector_->options(); }

 private:
  std::unique_ptr<det::Detector> detector_;
  det::ScanResult result_;
  std::mutex mutex_;
};

}  // namespace

void bind_detector(py::module_& m) {
  py::class_<PyDetection>(m, "Detection", R"(One tag found in a rotation.

position: tag centre (metres, sensor frame); orientation: quaternion w, x, y, z (tag frame to
sensor frame); rotation: the same as a 3x3 matrix; pose: 4x4 homogeneous transform (tag frame to
sensor frame); corners: the black square's corners (4x3: bottom-left, bottom-right, top-right,
top-left seen from the front); size_m: the configured tag size that matched (full printed
marker, white ring included).)")
      .def_readonly("family", &PyDetection::family)
      .def_readonly("family_index", &PyDetection::family_index)
      .def_readonly("id", &PyDetection::id)
      .def_readonly("size_m", &PyDetection::size_m)
      .def_readonly("position", &PyDetection::position)
      .def_readonly("orientation", &PyDetection::orientation)
      .def_readonly("rotation", &PyDetection::rotation)
      .def_readonly("pose", &PyDetection::pose)
      .def_readonly("corners", &PyDetection::corners)
      .def_readonly("score", &PyDetection::score)
      .def_readonly("margin", &PyDetection::margin)
      .def_readonly("points", &PyDetection::points)
      .def_readonly("fit_cost", &PyDetection::fit_cost)
      .def_readonly("time_first_s", &PyDetection::time_first_s,
                    "When the beams crossed the tag's first point, seconds after the rotation's "
                    "stamp (DetectionResult.stamp_ns).")
      .def_readonly("time_center_s", &PyDetection::time_center_s,
                    "When they crossed the point nearest its centre (seconds after the stamp).")
      .def_readonly("time_last_s", &PyDetection::time_last_s,
                    "When they crossed its last point (seconds after the stamp).")
      .def_readonly("measured_size_m", &PyDetection::measured_size_m,
                    "The size check: the marker's size its points measure (its black square), "
                    "metres; -1 when they do not tell it.")
      .def_readonly("size_warning", &PyDetection::size_warning,
                    "measured_size_m differs from size_m (the configured size) by more than "
                    "pose.size_warning_ratio: the configured size is wrong and the pose biased.")
      .def_readonly("deskew", &PyDetection::deskew,
                    "What moved its points to time_center_s before the fits (detector.deskew): "
                    "'none' (fitted as fired), 'ego' (odometry) or 'model' (a tracker's motion "
                    "model); the CLI's JSON key of the same name.")
      .def("__repr__", [](const PyDetection& d) {
        return "<lidartag.Detection " + d.family + " id " + std::to_string(d.id) + " at [" +
               std::to_string(d.position.x()) + ", " + std::to_string(d.position.y()) + ", " +
               std::to_string(d.position.z()) + "] m, score " + std::to_string(d.score) +
               (d.size_warning ? ", SIZE: measures " + std::to_string(d.measured_size_m) + " m"
                               : "") +
               ">";
      });

  py::class_<PyResult>(m, "DetectionResult",
                       "The detections of one rotation (a sequence of Detection) and what the "
                       "detector measured: features, clusters, timing_ms and rejected per stage.")
      .def_readonly("detections", &PyResult::detections)
      .def_readonly("features", &PyResult::features)
      .def_readonly("clusters", &PyResult::clusters)
      .def_readonly("deskewed_ego", &PyResult::deskewed_ego,
                    "With detector.deskew.enabled: validated clusters whose points were moved to "
                    "their centre time by odometry (never here: Detector.detect takes no motion).")
      .def_readonly("deskewed_model", &PyResult::deskewed_model,
                    "... by a tracker's motion model (never here: Detector.detect takes no "
                    "motion).")
      .def_readonly("deskew_without_motion", &PyResult::deskew_without_motion,
                    "... fitted as fired, no motion known for them (every validated cluster with "
                    "the deskew on: Detector.detect takes no motion). The CLI's JSON 'deskew'.")
      .def_readonly("timing_ms", &PyResult::timing_ms)
      .def_readonly("rejected", &PyResult::rejected)
      .def_readonly("total_ms", &PyResult::total_ms)
      .def_property_readonly(
          "diagnostics",
          [](const PyResult& r) {
            py::list out;
            for (size_t k = 0; k < r.diagnostics.size(); ++k) {
              py::dict d = py::cast(r.diagnostics[k]);
              d["result"] = r.diagnostic_results[k];
              out.append(d);
            }
            return out;
          },
          "Per cluster (Detector(..., diagnostics=True)): what each stage measured, -1 where it "
          "did not get that far, and result 'stage/reason'.")
      .def_readonly("stamp_ns", &PyResult::stamp_ns)
      .def_readonly("sequence", &PyResult::sequence)
      .def("__len__", [](const PyResult& r) { return r.detections.size(); })
      .def("__getitem__",
           [](const PyResult& r, py::ssize_t i) {
             const auto n = static_cast<py::ssize_t>(r.detections.size());
             if (i < 0) i += n;
             if (i < 0 || i >= n) throw py::index_error();
             return r.detections[static_cast<size_t>(i)];
           })
      .def("__iter__", [](const PyResult& r) { return py::iter(py::cast(r.detections)); })
      .def("__repr__", [](const PyResult& r) {
        return "<lidartag.DetectionResult " + std::to_string(r.detections.size()) +
               " detections, " + std::to_string(r.clusters) + " clusters, " +
               std::to_string(r.total_ms) + " ms>";
      });

  py::class_<PyDetector>(m, "Detector", R"(The LiDARTag detector.

Detector(config=None, diagnostics=False): config sets the options as lidartagd's YAML does, with
the daemon's own mapping (config/lidartagd.yaml lists every key): None for the defaults, a path
to a YAML file (its `detector:` section), a YAML document (text with a `detector:` section), or a
dict (the `detector:` section itself, or a whole configuration with a `detector` key), e.g.
{"tag_sizes_m": [0.8, 0.6], "families": ["tag16h5"]}. Bad keys or values raise ConfigError naming
the key. diagnostics=True also records what happened to every cluster.)")
      .def(py::init([](const py::object& config, bool diagnostics) {
             det::DetectorOptions options = options_of(config);
             options.cluster_diagnostics = diagnostics;
             return std::make_unique<PyDetector>(std::move(options));
           }),
           py::arg("config") = py::none(), py::arg("diagnostics") = false)
      .def("detect", &PyDetector::detect, py::arg("rotation"),
           "The detections of one Rotation (a DetectionResult). Runs without the GIL.")
      .def(
          "detect",
          [](PyDetector& d, const py::object& points, int rings,
             const std::optional<std::string>& model, double resolution_deg) {
            const Rotation rotation =
                Rotation::from_points(points, rings, model, resolution_deg, 0, 0);
            return d.detect(rotation);
          },
          py::arg("points"), py::kw_only(), py::arg("rings") = 0, py::arg("model") = py::none(),
          py::arg("resolution_deg") = 0.0,
          "The detections of a point cloud from any source: a numpy structured array or a dict "
          "of arrays, as Rotation.from_points takes (rings, model and resolution_deg as there).")
      .def_property_readonly("tag_sizes_m",
                             [](const PyDetector& d) { return d.options().tag_sizes_m; })
      .def_property_readonly("families", [](const PyDetector& d) { return d.options().families; });
}

}  // namespace lidartag::python
