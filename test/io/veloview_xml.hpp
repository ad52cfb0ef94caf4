// Writes calibrations as VeloView db.xml files, for the calibration tests and the fuzz seeds.
#pragma once

#include <tinyxml2.h>

#include <string>

#include "lidartag/driver/velodyne/calibration.hpp"

namespace lidartag::test {

// A VeloView db.xml of `c` as VeloView writes it (a boost::serialization archive: angles in
// degrees, lengths in centimetres, with the elements a reader must skip), written with tinyxml2.
inline std::string veloview_xml(const velodyne::Calibration& c, int count = -1) {
  const auto n = static_cast<int>(c.lasers.size());
  tinyxml2::XMLPrinter out;
  out.PushHeader(false, true);
  out.PushUnknown("DOCTYPE boost_serialization");
  out.OpenElement("boost_serialization");
  out.PushAttribute("signature", "serialization::archive");
  out.PushAttribute("version", "4");
  out.OpenElement("DB");
  out.PushAttribute("class_id", "0");
  auto value = [&](const char* name, double v) {
    out.OpenElement(name, true);
    out.PushText(v);
    out.CloseElement(true);
  };
  auto list = [&](const char* name, int items, double v) {
    out.OpenElement(name);
    value("count", items);
    value("item_version", 0);
    for (int i = 0; i < items; ++i) value("item", v);
    out.CloseElement();
  };
  value("distLSB_", c.distance_unit_m * 100.0);
  out.OpenElement("position_");
  out.OpenElement("xyz");
  value("count", 3);
  for (int k = 0; k < 3; ++k) value("item", 0);
  out.CloseElement();
  out.CloseElement();
  list("enabled_", n, 1);
  list("intensity_", n, 1);
  list("minIntensity_", n, 0);
  list("maxIntensity_", n, 255);
  out.OpenElement("points_");
  out.PushAttribute("class_id", "7");
  value("count", count < 0 ? n : count);
  value("item_version", 1);
  for (int i = 0; i < n; ++i) {
    const velodyne::LaserCorrection& l = c.lasers[static_cast<size_t>(i)];
    out.OpenElement("item");
    out.OpenElement("px");
    out.PushAttribute("class_id_reference", "9");
    value("id_", i);
    value("rotCorrection_", l.azimuth_offset_deg);
    value("vertCorrection_", l.elevation_deg);
    value("distCorrection_", l.distance_offset_m * 100.0);
    value("distCorrectionX_", 0);
    value("distCorrectionY_", 0);
    value("vertOffsetCorrection_", l.vertical_offset_m * 100.0);
    value("horizOffsetCorrection_", l.horizontal_offset_m * 100.0);
    value("focalDistance_", 0);
    value("focalSlope_", 0);
    out.CloseElement();
    out.CloseElement();
  }
  out.CloseElement();
  out.CloseElement();
  out.CloseElement();
  return out.CStr();
}

}  // namespace lidartag::test
