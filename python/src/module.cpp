// The extension module lidartag._lidartag; the package python/lidartag/__init__.py re-exports it.
#include "bindings.hpp"
#include "lcm_types.hpp"

#ifndef LIDARTAG_VERSION
#error "LIDARTAG_VERSION is set by python/CMakeLists.txt"
#endif

namespace py = pybind11;

PYBIND11_MODULE(_lidartag, m) {
  namespace lp = lidartag::python;
  m.doc() =
      "lidartag: Velodyne captures into numpy, the LiDARTag detector, the simulator, "
      "lidartagd's LCM logs, camera-LiDAR calibration";
  m.attr("__version__") = LIDARTAG_VERSION;
  lp::bind_errors(m);
  lp::bind_rotation(m);
  lp::bind_detector(m);
  lp::bind_sim(m);
  lp::bind_calib(m);
  py::module_ types = m.def_submodule("lcmtypes", "lidartagd's LCM message types (lcmtypes/*.lcm)");
  lp::bind_lcm_types(types);
  lp::bind_lcm_log(m);
}
