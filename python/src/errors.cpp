// C++ setup errors as Python exceptions, all subclasses of lidartag.Error (a RuntimeError).
#include "lidartag/driver/io/errors.hpp"

#include "bindings.hpp"
#include "lidartag/daemon/config.hpp"
#include "lidartag/detector/cloud_scan.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/detector/tag_family.hpp"
#include "lidartag/driver/ouster/metadata.hpp"
#include "lidartag/driver/velodyne/io/calibration_file.hpp"
#include "lidartag/sim/scene.hpp"
#include "lidartag/sim/truth.hpp"

namespace lidartag::python {

void bind_errors(py::module_& m) {
  // Created once; kept alive by the module.
  PyObject* base = PyErr_NewExceptionWithDoc("lidartag.Error",
                                             "A file, configuration or scene lidartag cannot use.",
                                             PyExc_RuntimeError, nullptr);
  m.add_object("Error", py::handle(base));
  py::register_exception<driver::IoError>(m, "IoError", base);
  py::register_exception<velodyne::CalibrationError>(m, "CalibrationError", base);
  // Ouster metadata that cannot describe a sensor, or that the capture's packets contradict.
  py::register_exception<driver::ouster::MetadataError>(m, "MetadataError", base);
  py::register_exception<daemon::ConfigError>(m, "ConfigError", base);
  py::register_exception<detector::OptionsError>(m, "OptionsError", base);
  py::register_exception<detector::CloudError>(m, "CloudError", base);
  py::register_exception<tags::FamilyError>(m, "FamilyError", base);
  py::register_exception<sim::SceneError>(m, "SceneError", base);
  py::register_exception<sim::OutputError>(m, "OutputError", base);
}

}  // namespace lidartag::python
