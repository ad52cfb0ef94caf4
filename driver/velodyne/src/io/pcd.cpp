#include "lidartag/driver/velodyne/io/pcd.hpp"

#include <lzf.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <string_view>
#include <unordered_set>

namespace lidartag::velodyne {
namespace {

// ---- Writing ----

// The fields write_pcd writes, in order.
struct FieldSpec {
  const char* name;
  char type;
  size_t size;
};
constexpr FieldSpec kFields[] = {{"x", 'F', 4},         {"y", 'F', 4},          {"z", 'F', 4},
                                 {"intensity", 'F', 4}, {"ring", 'U', 2},       {"azimuth", 'F', 4},
                                 {"time", 'F', 4},      {"return_type", 'U', 1}};
constexpr size_t kFieldCount = std::size(kFields);
constexpr size_t kPointSize = 4 + 4 + 4 + 4 + 2 + 4 + 4 + 1;

struct OutPoint {
  float x, y, z, intensity;
  uint16_t ring;
  float azimuth, time;
  uint8_t return_type;
};

template <typename T>
void put(char*& p, T value) {
  std::memcpy(p, &value, sizeof(T));
  p += sizeof(T);
}

// Field `f` of `point` at `p` (little-endian, the machine's order on the platforms built for).
void put_field(char*& p, const OutPoint& point, size_t f) {
  switch (f) {
    case 0:
      put(p, point.x);
      break;
    case 1:
      put(p, point.y);
      break;
    case 2:
      put(p, point.z);
      break;
    case 3:
      put(p, point.intensity);
      break;
    case 4:
      put(p, point.ring);
      break;
    case 5:
      put(p, point.azimuth);
      break;
    case 6:
      put(p, point.time);
      break;
    default:
      put(p, point.return_type);
      break;
  }
}

// Shortest text that reads back as the same float ("nan" for NaN, as PCL writes it).
void append_number(std::string& out, float v) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), v);
  out.append(buffer, result.ptr);
}

void append_ascii(std::string& out, const OutPoint& p) {
  for (float v : {p.x, p.y, p.z, p.intensity}) {
    append_number(out, v);
    out += ' ';
  }
  out += std::to_string(p.ring);
  out += ' ';
  append_number(out, p.azimuth);
  out += ' ';
  append_number(out, p.time);
  out += ' ';
  out += std::to_string(p.return_type);
  out += '\n';
}

std::vector<OutPoint> collect(const Scan& scan, bool organized, size_t& valid) {
  std::vector<OutPoint> points;
  valid = 0;
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  for (int ret = 0; ret < scan.returns; ++ret) {
    for (int ring = 0; ring < scan.rings; ++ring) {
      for (int col = 0; col < scan.columns; ++col) {
        const size_t i = scan.at(ret, ring, col);
        const auto ring16 = static_cast<uint16_t>(ring);
        if (scan.valid(i)) {
          ++valid;
          points.push_back({scan.x[i], scan.y[i], scan.z[i], static_cast<float>(scan.intensity[i]),
                            ring16, scan.azimuth_deg[i], scan.time_s[i],
                            static_cast<uint8_t>(scan.return_type[i])});
        } else if (organized) {
          // The decoder gives every cell its laser's firing azimuth and time, return or not.
          points.push_back(
              {kNaN, kNaN, kNaN, 0.0f, ring16, scan.azimuth_deg[i], scan.time_s[i], 0});
        }
      }
    }
  }
  return points;
}

std::string header(const Scan& scan, const PcdWriteOptions& options, size_t width, size_t height) {
  std::ostringstream out;
  out << "# .PCD v0.7 - Point Cloud Data file format\n";
  out << "# stamp_ns " << scan.stamp_ns << "\n";
  out << "# sequence " << scan.sequence << "\n";
  const auto models = all_models();
  if (std::find(models.begin(), models.end(), static_cast<Model>(scan.model)) != models.end())
    out << "# model " << model_spec(static_cast<Model>(scan.model)).name << "\n";
  if (const auto mode = return_mode_from_byte(scan.return_mode))
    out << "# return_mode " << return_mode_name(*mode) << "\n";
  out << "# complete " << (scan.complete ? 1 : 0) << "\n";
  out << "# rpm " << scan.rpm << "\n";
  out << "VERSION 0.7\nFIELDS";
  for (const auto& f : kFields) out << ' ' << f.name;
  out << "\nSIZE";
  for (const auto& f : kFields) out << ' ' << f.size;
  out << "\nTYPE";
  for (const auto& f : kFields) out << ' ' << f.type;
  out << "\nCOUNT";
  for (size_t f = 0; f < kFieldCount; ++f) out << " 1";
  out << "\nWIDTH " << width << "\nHEIGHT " << height << "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS "
      << width * height << "\nDATA " << pcd_format_name(options.format) << "\n";
  return out.str();
}

std::string data(const std::vector<OutPoint>& points, PcdFormat format, const std::string& path) {
  std::string bytes;
  if (format == PcdFormat::kAscii) {
    for (const auto& p : points) append_ascii(bytes, p);
    return bytes;
  }
  bytes.resize(points.size() * kPointSize);
  char* p = bytes.data();
  if (format == PcdFormat::kBinary) {
    for (const auto& point : points)
      for (size_t f = 0; f < kFieldCount; ++f) put_field(p, point, f);
    return bytes;
  }
  // binary_compressed: every point's first field, then every point's second, ... (what PCL
  // writes), LZF-compressed behind two uint32: compressed and uncompressed size.
  for (size_t f = 0; f < kFieldCount; ++f)
    for (const auto& point : points) put_field(p, point, f);
  if (bytes.size() > std::numeric_limits<uint32_t>::max() / 2) {
    throw driver::IoError("PCD file '" + path + "': too many points for binary_compressed");
  }
  // LZF output is at most 1 byte per 32 larger than its input.
  std::string packed(8 + bytes.size() + bytes.size() / 32 + 16, '\0');
  const unsigned in_len = static_cast<unsigned>(bytes.size());
  const unsigned out_len = static_cast<unsigned>(packed.size() - 8);
  const unsigned compressed =
      in_len == 0 ? 0 : lzf_compress(bytes.data(), in_len, packed.data() + 8, out_len);
  if (in_len > 0 && compressed == 0) {
    throw driver::IoError("PCD file '" + path + "': LZF compression failed");
  }
  std::memcpy(packed.data(), &compressed, 4);
  std::memcpy(packed.data() + 4, &in_len, 4);
  packed.resize(8 + compressed);
  return packed;
}

// ---- Reading ----

driver::IoError pcd_error(const std::string& path, const std::string& problem) {
  return driver::IoError("PCD file '" + path + "': " + problem);
}

template <typename T>
T get(const char* p) {
  T value;
  std::memcpy(&value, p, sizeof(T));
  return value;
}

double read_value(const char* p, char type, size_t size) {
  switch (type) {
    case 'F':
      return size == 4 ? get<float>(p) : get<double>(p);
    case 'U':
      return size == 1   ? get<uint8_t>(p)
             : size == 2 ? get<uint16_t>(p)
             : size == 4 ? get<uint32_t>(p)
                         : static_cast<double>(get<uint64_t>(p));
    default:
      return size == 1   ? get<int8_t>(p)
             : size == 2 ? get<int16_t>(p)
             : size == 4 ? get<int32_t>(p)
                         : static_cast<double>(get<int64_t>(p));
  }
}

// A whole word as a number; PCL writes "nan" for the invalid points of organised clouds.
bool parse_number(const std::string& word, double& v) {
  const char* end = word.data() + word.size();
  const char* begin = word.data() + (word.size() > 1 && word[0] == '+' ? 1 : 0);
  const auto [p, ec] = std::from_chars(begin, end, v);
  return ec == std::errc() && p == end;
}

template <typename T>
bool parse_integer(const std::string& word, T& v) {
  const auto [p, ec] = std::from_chars(word.data(), word.data() + word.size(), v);
  return ec == std::errc() && p == word.data() + word.size();
}

// "# key value" comments of write_pcd; other comments are ignored.
void read_comment(const std::string& line, const std::string& path, PcdRotation& rotation) {
  std::istringstream words(line.substr(1));
  std::string key, value, extra;
  if (!(words >> key >> value) || (words >> extra)) return;
  const auto bad = [&](const char* expected) {
    return pcd_error(path, "header comment '" + key + "': '" + value + "' is not " + expected);
  };
  if (key == "stamp_ns") {
    int64_t v = 0;
    if (!parse_integer(value, v)) throw bad("a time in ns");
    rotation.stamp_ns = v;
  } else if (key == "sequence") {
    uint64_t v = 0;
    if (!parse_integer(value, v)) throw bad("a rotation number");
    rotation.sequence = v;
  } else if (key == "model") {
    rotation.model = model_from_name(value);
    if (!rotation.model) throw bad(("a model (" + model_names() + ")").c_str());
  } else if (key == "return_mode") {
    for (const ReturnMode mode : {ReturnMode::kStrongest, ReturnMode::kLast, ReturnMode::kDual})
      if (value == return_mode_name(mode)) rotation.return_mode = static_cast<uint8_t>(mode);
    if (!rotation.return_mode) throw bad("strongest, last or dual");
  } else if (key == "complete") {
    if (value != "0" && value != "1") throw bad("0 or 1");
    rotation.complete = value == "1";
  } else if (key == "rpm") {
    double v = 0;
    if (!parse_number(value, v) || !(v >= 0.0 && v < 1e5)) throw bad("a rotation rate");
    rotation.rpm = static_cast<float>(v);
  }
}

struct Layout {
  std::vector<std::string> names;
  std::vector<size_t> sizes, counts;
  std::vector<char> types;
  std::vector<int> column;  // index in PcdCloud::columns, -1 when skipped
  size_t point_size = 0;
};

}  // namespace

std::string_view pcd_format_name(PcdFormat format) {
  switch (format) {
    case PcdFormat::kAscii:
      return "ascii";
    case PcdFormat::kBinary:
      return "binary";
    case PcdFormat::kBinaryCompressed:
      return "binary_compressed";
  }
  return "binary";
}

size_t write_pcd(const std::string& path, const Scan& scan, const PcdWriteOptions& options) {
  size_t valid = 0;
  const std::vector<OutPoint> points = collect(scan, options.organized, valid);
  const size_t width = options.organized ? static_cast<size_t>(scan.columns) : points.size();
  const size_t height =
      options.organized ? static_cast<size_t>(scan.rings) * static_cast<size_t>(scan.returns) : 1;
  const std::string body = data(points, options.format, path);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw driver::IoError("cannot create PCD file '" + path + "'");
  out << header(scan, options, width, height);
  out.write(body.data(), static_cast<std::streamsize>(body.size()));
  out.close();
  if (!out) throw driver::IoError("cannot write PCD file '" + path + "'");
  return valid;
}

void apply_pcd_rotation(const PcdRotation& rotation, Scan& scan) {
  if (rotation.stamp_ns) scan.stamp_ns = *rotation.stamp_ns;
  if (rotation.sequence) scan.sequence = *rotation.sequence;
  if (rotation.model) scan.model = static_cast<uint8_t>(*rotation.model);
  if (rotation.return_mode) scan.return_mode = *rotation.return_mode;
  if (rotation.complete) scan.complete = *rotation.complete;
  if (rotation.rpm) scan.rpm = *rotation.rpm;
}

PcdCloud read_pcd_points(const std::string& path) {
  PcdCloud cloud = read_pcd(path);
  for (const char* axis : {"x", "y", "z"})
    if (!cloud.has(axis)) throw pcd_error(path, std::string("no '") + axis + "' field");
  return cloud;
}

void pcd_cloud_columns(const PcdCloud& cloud, driver::CloudColumns& out) {
  std::vector<driver::CloudSourceField> fields;
  fields.reserve(cloud.fields.size());
  for (size_t f = 0; f < cloud.fields.size(); ++f)
    fields.push_back({cloud.fields[f], f < cloud.types.size() && cloud.types[f] != 'F'});
  driver::cloud_columns_of(
      fields, [&](size_t k, std::vector<double>& values) { values = cloud.columns[k]; }, out);
  out.width = cloud.width;
  out.height = cloud.height;
}

bool PcdCloud::has(const std::string& name) const {
  return std::find(fields.begin(), fields.end(), name) != fields.end();
}

const std::vector<double>& PcdCloud::field(const std::string& name) const {
  const auto it = std::find(fields.begin(), fields.end(), name);
  if (it == fields.end()) throw driver::IoError("PCD cloud has no field '" + name + "'");
  return columns[static_cast<size_t>(it - fields.begin())];
}

namespace {
constexpr size_t kMaxPcdFields = 4096;
}  // namespace

PcdCloud read_pcd(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw pcd_error(path, "cannot open");
  PcdCloud cloud;
  Layout layout;
  size_t points = 0;
  bool have_points = false;
  std::string data_kind;
  std::string line;
  while (data_kind.empty()) {
    if (!std::getline(in, line)) throw pcd_error(path, "header ends before DATA");
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    if (line[0] == '#') {
      read_comment(line, path, cloud.rotation);
      continue;
    }
    std::istringstream words(line);
    std::string key;
    words >> key;
    if (key == "FIELDS") {
      for (std::string f; words >> f;) layout.names.push_back(f);
    } else if (key == "SIZE") {
      for (size_t s; words >> s;) layout.sizes.push_back(s);
    } else if (key == "TYPE") {
      for (std::string t; words >> t;) layout.types.push_back(t.size() == 1 ? t[0] : '?');
    } else if (key == "COUNT") {
      for (size_t c; words >> c;) layout.counts.push_back(c);
    } else if (key == "WIDTH") {
      words >> cloud.width;
    } else if (key == "HEIGHT") {
      words >> cloud.height;
    } else if (key == "POINTS") {
      have_points = static_cast<bool>(words >> points);
    } else if (key == "DATA") {
      words >> data_kind;
      if (data_kind.empty()) throw pcd_error(path, "DATA without a kind");
    } else if (key != "VERSION" && key != "VIEWPOINT") {
      throw pcd_error(path, "unknown header line '" + line + "'");
    }
    if (words.fail() && !words.eof()) throw pcd_error(path, "bad header line '" + line + "'");
  }
  const size_t n_fields = layout.names.size();
  if (n_fields == 0) throw pcd_error(path, "no FIELDS");
  // Real clouds have a handful of fields; a header of 200,000 once took 28 s.
  if (n_fields > kMaxPcdFields) {
    throw pcd_error(path, std::to_string(n_fields) + " FIELDS, more than the limit of " +
                              std::to_string(kMaxPcdFields));
  }
  std::unordered_set<std::string> seen;  // names taken, for the duplicate check in linear time
  if (layout.sizes.size() != n_fields || layout.types.size() != n_fields) {
    throw pcd_error(path, "FIELDS, SIZE and TYPE disagree in length");
  }
  if (layout.counts.empty()) layout.counts.assign(n_fields, 1);
  if (layout.counts.size() != n_fields)
    throw pcd_error(path, "COUNT disagrees with FIELDS in length");
  if (cloud.width == 0 && cloud.height <= 1 && have_points && points > 0) {
    // A writer that filled its points but never set WIDTH (PCL's with points pushed one by one):
    // the points are all there, as one row.
    cloud.width = points;
    cloud.width_from_points = true;
  }
  if (cloud.height == 0) cloud.height = 1;
  // WIDTH x HEIGHT must not wrap around: 2^32 x 2^32 would read as an empty cloud.
  if (cloud.width > std::numeric_limits<size_t>::max() / cloud.height) {
    throw pcd_error(path, "WIDTH x HEIGHT (" + std::to_string(cloud.width) + " x " +
                              std::to_string(cloud.height) + ") is out of range");
  }
  if (!have_points) points = cloud.width * cloud.height;
  if (points != cloud.width * cloud.height) throw pcd_error(path, "POINTS is not WIDTH x HEIGHT");
  for (size_t f = 0; f < n_fields; ++f) {
    const std::string& name = layout.names[f];
    const char t = layout.types[f];
    const size_t s = layout.sizes[f];
    const bool ok = (t == 'F' && (s == 4 || s == 8)) ||
                    ((t == 'U' || t == 'I') && (s == 1 || s == 2 || s == 4 || s == 8));
    if (!ok) {
      throw pcd_error(path, "field '" + name + "' has unsupported type " + std::string(1, t) +
                                std::to_string(s));
    }
    if (layout.counts[f] == 0 || layout.counts[f] > 4096) {
      throw pcd_error(path, "field '" + name + "' has COUNT " + std::to_string(layout.counts[f]));
    }
    layout.point_size += s * layout.counts[f];
    if (name == "_" || layout.counts[f] != 1) {
      layout.column.push_back(-1);
      cloud.skipped_fields.push_back(name);
      continue;
    }
    if (!seen.insert(name).second) throw pcd_error(path, "field '" + name + "' appears twice");
    layout.column.push_back(static_cast<int>(cloud.fields.size()));
    cloud.fields.push_back(name);
    cloud.types.push_back(t);
  }
  if (data_kind == "ascii") {
    cloud.format = PcdFormat::kAscii;
  } else if (data_kind == "binary") {
    cloud.format = PcdFormat::kBinary;
  } else if (data_kind == "binary_compressed") {
    cloud.format = PcdFormat::kBinaryCompressed;
  } else {
    throw pcd_error(path,
                    "DATA " + data_kind + " not supported (ascii, binary, binary_compressed)");
  }
  // A corrupt header must not make us allocate more than the file could hold.
  const std::streamoff here = in.tellg();
  in.seekg(0, std::ios::end);
  const auto remaining = static_cast<size_t>(std::max<std::streamoff>(0, in.tellg() - here));
  in.seekg(here);
  size_t values_per_point = 0;
  for (size_t c : layout.counts) values_per_point += c;
  // ascii: at least a digit and a separator per value; binary: the point's bytes; compressed:
  // an LZF back reference of 3 bytes unpacks to at most 264, so the data unpacks to at most 88
  // times its size (and zero-size points are bounded by the uncompressed size check below).
  const size_t capacity = cloud.format == PcdFormat::kAscii ? remaining / (2 * values_per_point)
                          : cloud.format == PcdFormat::kBinary
                              ? remaining / layout.point_size
                              : (remaining / layout.point_size + 1) * 88;
  if (points > capacity + 1) {
    throw pcd_error(path, std::to_string(points) + " points cannot fit in the " +
                              std::to_string(remaining) + " bytes of data");
  }
  cloud.columns.assign(cloud.fields.size(), std::vector<double>(points));

  if (cloud.format == PcdFormat::kAscii) {
    // Word by word with from_chars: istream's >> refuses the "nan" that PCL writes for
    // invalid points, and would call that the end of the data.
    std::string word;
    for (size_t i = 0; i < points; ++i) {
      for (size_t f = 0; f < n_fields; ++f) {
        for (size_t k = 0; k < layout.counts[f]; ++k) {
          if (!(in >> word)) throw pcd_error(path, "ascii data ends at point " + std::to_string(i));
          double v = 0;
          if (!parse_number(word, v)) {
            throw pcd_error(path, "ascii value '" + word + "' of field '" + layout.names[f] +
                                      "' at point " + std::to_string(i) + " is not a number");
          }
          // An F4 field holds floats: the text's nearest float, as a binary file would hold.
          if (layout.types[f] == 'F' && layout.sizes[f] == 4 &&
              !(std::fabs(v) > std::numeric_limits<float>::max()))
            v = static_cast<double>(static_cast<float>(v));
          if (layout.column[f] >= 0) cloud.columns[static_cast<size_t>(layout.column[f])][i] = v;
        }
      }
    }
    return cloud;
  }

  const size_t data_size = points * layout.point_size;
  std::vector<char> bytes(data_size);
  if (cloud.format == PcdFormat::kBinary) {
    in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (static_cast<size_t>(in.gcount()) != bytes.size()) {
      throw pcd_error(path, "binary data holds " + std::to_string(in.gcount()) + " of " +
                                std::to_string(bytes.size()) + " bytes");
    }
    const char* p = bytes.data();
    for (size_t i = 0; i < points; ++i) {
      for (size_t f = 0; f < n_fields; ++f) {
        if (layout.column[f] >= 0)
          cloud.columns[static_cast<size_t>(layout.column[f])][i] =
              read_value(p, layout.types[f], layout.sizes[f]);
        p += layout.sizes[f] * layout.counts[f];
      }
    }
    return cloud;
  }

  // binary_compressed: uint32 compressed size, uint32 uncompressed size, LZF data holding each
  // field of every point in turn.
  char sizes[8];
  in.read(sizes, 8);
  if (in.gcount() != 8) throw pcd_error(path, "binary_compressed data ends before its sizes");
  const uint32_t compressed = get<uint32_t>(sizes);
  const uint32_t uncompressed = get<uint32_t>(sizes + 4);
  if (uncompressed != data_size) {
    throw pcd_error(path, "binary_compressed data unpacks to " + std::to_string(uncompressed) +
                              " bytes, but " + std::to_string(points) + " points of " +
                              std::to_string(layout.point_size) + " bytes need " +
                              std::to_string(data_size));
  }
  if (compressed > remaining - std::min<size_t>(remaining, 8)) {
    throw pcd_error(path, "binary_compressed data holds " +
                              std::to_string(remaining - std::min<size_t>(remaining, 8)) + " of " +
                              std::to_string(compressed) + " compressed bytes");
  }
  std::vector<char> packed(compressed);
  in.read(packed.data(), static_cast<std::streamsize>(packed.size()));
  if (static_cast<size_t>(in.gcount()) != packed.size()) {
    throw pcd_error(path, "binary_compressed data is shorter than its size");
  }
  if (data_size > 0) {
    const unsigned got =
        compressed == 0 ? 0 : lzf_decompress(packed.data(), compressed, bytes.data(), uncompressed);
    if (got != uncompressed) {
      throw pcd_error(path, "binary_compressed data is corrupt (LZF gave " + std::to_string(got) +
                                " of " + std::to_string(uncompressed) + " bytes)");
    }
  }
  size_t offset = 0;
  for (size_t f = 0; f < n_fields; ++f) {
    const size_t stride = layout.sizes[f] * layout.counts[f];
    if (layout.column[f] >= 0) {
      auto& column = cloud.columns[static_cast<size_t>(layout.column[f])];
      for (size_t i = 0; i < points; ++i)
        column[i] =
            read_value(bytes.data() + offset + i * stride, layout.types[f], layout.sizes[f]);
    }
    offset += stride * points;
  }
  return cloud;
}

}  // namespace lidartag::velodyne
