// VeloView / Velodyne db.xml calibration files (a boost::serialization archive):
//   boost_serialization > DB > distLSB_ (cm), points_ > count, item* > px > id_, rotCorrection_,
//   vertCorrection_ (degrees), distCorrection_, distCorrectionX_, distCorrectionY_,
//   vertOffsetCorrection_, horizOffsetCorrection_, focalDistance_ (cm), focalSlope_.
// Parsed with tinyxml2; the numbers are read strictly (the whole text, finite).
#include <tinyxml2.h>

#include <charconv>
#include <cmath>
#include <optional>
#include <string_view>

#include "calibration_entries.hpp"
#include "lidartag/driver/velodyne/io/calibration_file.hpp"

namespace lidartag::velodyne::detail {
namespace {

constexpr double kMetresPerCm = 0.01;

std::string_view trimmed(const char* text) {
  std::string_view s = text ? text : "";
  const auto first = s.find_first_not_of(" \t\r\n");
  if (first == std::string_view::npos) return {};
  return s.substr(first, s.find_last_not_of(" \t\r\n") - first + 1);
}

// The element's text as a finite number; empty when the element is absent.
std::optional<double> number(const tinyxml2::XMLElement* parent, const char* name,
                             const std::string& where, const std::string& path) {
  const tinyxml2::XMLElement* element = parent->FirstChildElement(name);
  if (element == nullptr) return std::nullopt;
  const std::string_view text = trimmed(element->GetText());
  double value = 0;
  const char* begin = text.data();
  const char* end = text.data() + text.size();
  if (!text.empty() && *begin == '+') ++begin;
  const auto [ptr, ec] = std::from_chars(begin, end, value);
  if (text.empty() || ec != std::errc() || ptr != end || !std::isfinite(value)) {
    throw CalibrationError(path, where + name, "not a number ('" + std::string(text) + "')");
  }
  return value;
}

double required_number(const tinyxml2::XMLElement* parent, const char* name,
                       const std::string& where, const std::string& path) {
  const auto value = number(parent, name, where, path);
  if (!value) throw CalibrationError(path, where + name, "missing");
  return *value;
}

}  // namespace

CalibrationEntries parse_calibration_xml(const std::string& path) {
  tinyxml2::XMLDocument doc;
  if (doc.LoadFile(path.c_str()) != tinyxml2::XML_SUCCESS) {
    throw CalibrationError(path, "",
                           std::string("not valid XML: ") + (doc.ErrorStr() ? doc.ErrorStr() : ""));
  }
  const tinyxml2::XMLElement* root = doc.RootElement();
  // The archive wraps the DB element; a bare DB is accepted too.
  const tinyxml2::XMLElement* db = root && std::string_view(root->Name()) == "DB" ? root
                                   : root ? root->FirstChildElement("DB")
                                          : nullptr;
  if (db == nullptr) {
    throw CalibrationError(path, "DB",
                           "missing: not a VeloView calibration (boost_serialization > DB)");
  }
  number(db, "distLSB_", "", path);  // validated only, as distance_resolution
  const tinyxml2::XMLElement* points = db->FirstChildElement("points_");
  if (points == nullptr) throw CalibrationError(path, "points_", "missing");

  CalibrationEntries entries;
  entries.list_key = "points_";
  entries.declared_key = "points_.count";
  entries.angle_unit = "degrees";
  entries.length_unit = "centimetres";
  if (const auto count = number(points, "count", "points_.", path)) {
    if (*count != std::floor(*count) || std::fabs(*count) > 1e6)
      throw CalibrationError(path, "points_.count", "not an integer");
    entries.declared = static_cast<int>(*count);
  }
  size_t i = 0;
  for (const tinyxml2::XMLElement* item = points->FirstChildElement("item"); item != nullptr;
       item = item->NextSiblingElement("item"), ++i) {
    LaserEntry e;
    e.where = "points_[" + std::to_string(i) + "]";
    const tinyxml2::XMLElement* px = item->FirstChildElement("px");
    if (px == nullptr) throw CalibrationError(path, e.where + ".px", "missing");
    const std::string prefix = e.where + ".";
    e.id_key = prefix + "id_";
    e.id = required_number(px, "id_", prefix, path);
    e.elevation_deg = {prefix + "vertCorrection_",
                       required_number(px, "vertCorrection_", prefix, path)};
    e.azimuth_offset_deg = {prefix + "rotCorrection_",
                            required_number(px, "rotCorrection_", prefix, path)};
    e.distance_offset_m = {
        prefix + "distCorrection_",
        number(px, "distCorrection_", prefix, path).value_or(0.0) * kMetresPerCm};
    e.vertical_offset_m = {
        prefix + "vertOffsetCorrection_",
        number(px, "vertOffsetCorrection_", prefix, path).value_or(0.0) * kMetresPerCm};
    e.horizontal_offset_m = {
        prefix + "horizOffsetCorrection_",
        number(px, "horizOffsetCorrection_", prefix, path).value_or(0.0) * kMetresPerCm};
    // Every other value of the entry (distCorrectionX_, focalSlope_, an HDL-64E's closeSlope_,
    // ...) is a number; kept for the all-zero rule of entries beyond the model's lasers.
    for (const tinyxml2::XMLElement* child = px->FirstChildElement(); child != nullptr;
         child = child->NextSiblingElement()) {
      const std::string name = child->Name();
      if (name == "id_") continue;
      e.numbers.push_back({prefix + name, *number(px, name.c_str(), prefix, path)});
    }
    entries.lasers.push_back(std::move(e));
  }
  return entries;
}

}  // namespace lidartag::velodyne::detail
