#include "lidartag/calib/intrinsics_file.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <sstream>
#include <vector>

namespace lidartag::calib {
namespace {

struct Reader {
  const std::string& origin;

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw IntrinsicsFileError(origin, key, what);
  }

  double number(const YAML::Node& n, const std::string& key) const {
    if (!n.IsScalar()) fail(key, "expected a number");
    try {
      return n.as<double>();
    } catch (const YAML::Exception&) {
      fail(key, "'" + n.Scalar() + "' is not a number");
    }
  }

  int integer(const YAML::Node& n, const std::string& key) const {
    const double v = number(n, key);
    if (!(v >= 0 && v <= 1e6) || v != static_cast<double>(static_cast<int>(v)))
      fail(key, "expected a whole number of pixels, got '" + n.Scalar() + "'");
    return static_cast<int>(v);
  }

  // A matrix as ROS ({rows, cols, data}) or OpenCV (!!opencv-matrix {rows, cols, dt, data}) write
  // it, or a plain sequence. Returns its values row-major; rows/cols when given must match.
  std::vector<double> matrix(const YAML::Node& n, const std::string& key, int* rows = nullptr,
                             int* cols = nullptr) const {
    // Copy-constructed, not assigned: Node assignment writes through to the node assigned to,
    // and reset() refuses a missing key's node.
    const YAML::Node data = n.IsMap() ? n["data"] : n;
    int r = -1, c = -1;
    if (n.IsMap()) {
      if (!data) fail(key, "matrix without 'data'");
      if (n["rows"]) r = integer(n["rows"], key + ".rows");
      if (n["cols"]) c = integer(n["cols"], key + ".cols");
      if (const YAML::Node dt = n["dt"];
          dt && dt.IsScalar() && dt.Scalar() != "d" && dt.Scalar() != "f")
        fail(key + ".dt", "element type '" + dt.Scalar() + "' is not a real number (d or f)");
    }
    if (data.IsNull()) return {};
    if (!data.IsSequence()) fail(key, "'data' must be a list of numbers");
    std::vector<double> v;
    for (std::size_t i = 0; i < data.size(); ++i)
      v.push_back(number(data[i], key + ".data[" + std::to_string(i) + "]"));
    if (r >= 0 && c >= 0 && static_cast<std::size_t>(r) * static_cast<std::size_t>(c) != v.size())
      fail(key, "rows x cols = " + std::to_string(r) + " x " + std::to_string(c) + " but " +
                    std::to_string(v.size()) + " values");
    if (rows) *rows = r;
    if (cols) *cols = c;
    return v;
  }
};

// The first of `keys` present in `root` (and its name), or a null node.
YAML::Node first_of(const YAML::Node& root, std::initializer_list<const char*> keys,
                    std::string* found) {
  for (const char* k : keys)
    if (YAML::Node n = root[k]; n) {
      *found = k;
      return n;
    }
  return YAML::Node(YAML::NodeType::Undefined);  // a default Node is a defined null
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  return s;
}

// OpenCV writes "%YAML:1.0" (and older versions "%YAML 1.0"), which yaml-cpp refuses; any YAML
// directive line is dropped, the document is the same without it.
std::string strip_directive(std::string_view text) {
  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);  // UTF-8 byte order mark
  if (text.substr(0, 5) == "%YAML") {
    const std::size_t eol = text.find('\n');
    text = eol == std::string_view::npos ? std::string_view{} : text.substr(eol + 1);
  }
  return std::string(text);
}

}  // namespace

static CameraModel parse_yaml(std::string_view text, const std::string& origin) {
  const Reader rd{origin};
  YAML::Node root;
  try {
    root = YAML::Load(strip_directive(text));
  } catch (const YAML::Exception& e) {
    rd.fail("", std::string("not YAML: ") + e.what());
  }
  if (!root.IsMap()) rd.fail("", "not a camera_info or OpenCV intrinsics file (no keys)");

  CameraModel cam;
  std::string key;
  // Image size: image_width / image_height (both formats), or OpenCV's image_size [w, h].
  if (YAML::Node w = root["image_width"], h = root["image_height"]; w || h) {
    if (!w) rd.fail("image_width", "missing (image_height is given)");
    if (!h) rd.fail("image_height", "missing (image_width is given)");
    cam.width = rd.integer(w, "image_width");
    cam.height = rd.integer(h, "image_height");
  } else if (YAML::Node s = first_of(root, {"image_size", "imageSize"}, &key); s) {
    const std::vector<double> v = rd.matrix(s, key);
    if (v.size() != 2) rd.fail(key, "expected [width, height]");
    cam.width = static_cast<int>(v[0]);
    cam.height = static_cast<int>(v[1]);
    if (cam.width != v[0] || cam.height != v[1]) rd.fail(key, "expected whole pixels");
  } else {
    rd.fail("image_width", "missing (the image size must be known to check the images)");
  }

  const YAML::Node k = first_of(root, {"camera_matrix", "K", "cameraMatrix", "intrinsics"}, &key);
  if (!k) rd.fail("camera_matrix", "missing (also looked for K, cameraMatrix)");
  int rows = -1, cols = -1;
  const std::vector<double> kv = rd.matrix(k, key, &rows, &cols);
  if (kv.size() != 9 || (rows >= 0 && rows != 3))
    rd.fail(key, "expected a 3 x 3 matrix, got " + std::to_string(kv.size()) + " values");
  if (kv[3] != 0 || kv[6] != 0 || kv[7] != 0 || kv[8] != 1)
    rd.fail(key, "not a camera matrix [fx s cx; 0 fy cy; 0 0 1]");
  cam.fx = kv[0];
  cam.skew = kv[1];
  cam.cx = kv[2];
  cam.fy = kv[4];
  cam.cy = kv[5];

  // The lens model: distortion_model (ROS, some OpenCV writers), else a fisheye flag, else
  // plumb-bob when there are coefficients.
  std::string model;
  std::string model_key = "distortion_model";
  if (YAML::Node m = root["distortion_model"]; m) {
    if (!m.IsScalar()) rd.fail("distortion_model", "expected a name");
    model = lower(m.Scalar());
  } else if (YAML::Node f =
                 first_of(root, {"fisheye", "is_fisheye", "use_fisheye_model"}, &model_key);
             f) {
    bool flag = false;
    if (!f.IsScalar()) rd.fail(model_key, "expected true/false or 1/0");
    if (f.Scalar() == "1") {
      flag = true;
    } else if (f.Scalar() != "0") {
      try {
        flag = f.as<bool>();
      } catch (const YAML::Exception&) {
        rd.fail(model_key, "expected true/false or 1/0, got '" + f.Scalar() + "'");
      }
    }
    model = flag ? "equidistant" : "";
  }
  std::vector<double> dv;
  std::string dkey = "distortion_coefficients";
  if (YAML::Node d =
          first_of(root, {"distortion_coefficients", "D", "distCoeffs", "dist_coeffs"}, &dkey);
      d)
    dv = rd.matrix(d, dkey);
  const bool all_zero = std::all_of(dv.begin(), dv.end(), [](double v) { return v == 0.0; });

  if (model == "rational_polynomial") {
    rd.fail(model_key,
            "rational_polynomial (8 coefficients) is not supported: plumb_bob (k1 k2 p1 p2 k3) "
            "or equidistant (k1 k2 k3 k4) only; recalibrate with one of those");
  } else if (model == "equidistant" || model == "fisheye" || model == "kannala_brandt") {
    if (dv.size() != 4)
      rd.fail(dkey, "equidistant (fisheye) takes 4 coefficients k1 k2 k3 k4, got " +
                        std::to_string(dv.size()));
    cam.distortion = Distortion::kEquidistant;
    std::copy(dv.begin(), dv.end(), cam.d.begin());
  } else if (model.empty() || model == "plumb_bob" || model == "radtan" || model == "pinhole") {
    if (dv.empty() || (model.empty() && all_zero)) {
      cam.distortion = Distortion::kNone;
    } else {
      // OpenCV: k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tx ty]]]]; only the first five are this
      // model's.
      if (dv.size() < 4 || dv.size() == 6 || dv.size() == 7 || dv.size() > 14)
        rd.fail(dkey,
                "plumb_bob takes 5 coefficients k1 k2 p1 p2 k3 (4, 8, 12, 14 from OpenCV), "
                "got " +
                    std::to_string(dv.size()));
      for (std::size_t i = 5; i < dv.size(); ++i)
        if (dv[i] != 0.0)
          rd.fail(dkey, "coefficient " + std::to_string(i) +
                            " (rational / thin-prism / tilt) is not zero: only plumb_bob's k1 k2 "
                            "p1 p2 k3 are supported");
      cam.distortion = Distortion::kPlumbBob;
      std::copy_n(dv.begin(), std::min<std::size_t>(dv.size(), 5), cam.d.begin());
    }
  } else if (model == "none") {
    if (!all_zero) rd.fail(dkey, "distortion_model none with non-zero coefficients");
    cam.distortion = Distortion::kNone;
  } else {
    rd.fail(model_key, "unknown model '" + model + "' (plumb_bob or equidistant)");
  }

  try {
    cam.check();
  } catch (const CameraModelError& e) {
    rd.fail("", e.what());
  }
  return cam;
}

CameraModel parse_intrinsics(std::string_view text, const std::string& origin) {
  try {
    return parse_yaml(text, origin);
  } catch (const YAML::Exception& e) {
    // A node of a form the reader did not expect: the key is in the message when yaml-cpp knows
    // it.
    throw IntrinsicsFileError(origin, "", std::string("malformed: ") + e.what());
  }
}

CameraModel load_intrinsics(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IntrinsicsFileError(path, "", "cannot open");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw IntrinsicsFileError(path, "", "read error");
  return parse_intrinsics(ss.str(), path);
}

}  // namespace lidartag::calib
