#include "lidartag/exit_codes.hpp"

#include "lidartag/calib/camera_model.hpp"
#include "lidartag/calib/image_tags.hpp"
#include "lidartag/calib/intrinsics_file.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/detector/tag_family.hpp"
#include "lidartag/driver/ouster/metadata.hpp"
#include "lidartag/driver/velodyne/io/calibration_file.hpp"
#include "lidartag/sim/scene.hpp"
#ifdef LIDARTAG_HAVE_CONFIG
#include "lidartag/daemon/config.hpp"
#endif

namespace lidartag::cli {

int exit_code_of(const std::exception& e) {
  if (dynamic_cast<const UsageError*>(&e) != nullptr ||
      dynamic_cast<const detector::OptionsError*>(&e) != nullptr ||
      dynamic_cast<const tags::FamilyError*>(&e) != nullptr ||
      dynamic_cast<const velodyne::CalibrationError*>(&e) != nullptr ||
      dynamic_cast<const driver::ouster::MetadataError*>(&e) != nullptr ||
      dynamic_cast<const sim::SceneError*>(&e) != nullptr ||
      dynamic_cast<const calib::IntrinsicsFileError*>(&e) != nullptr ||
      dynamic_cast<const calib::CameraModelError*>(&e) != nullptr ||
      dynamic_cast<const calib::ImageTagError*>(&e) != nullptr)
    return kExitUsage;
#ifdef LIDARTAG_HAVE_CONFIG
  if (dynamic_cast<const daemon::ConfigError*>(&e) != nullptr) return kExitUsage;
#endif
  return kExitRuntime;
}

}  // namespace lidartag::cli
