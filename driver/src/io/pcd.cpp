#include "lidartag/driver/io/pcd.hpp"

#include <algorithm>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

namespace lidartag::velodyne {
namespace {

// One point as written: packed little-endian fields, 24 bytes.
constexpr size_t kPointSize = 4 * 3 + 4 + 2 + 4 + 4 + 1;

template <typename T>
void put(uint8_t*& p, T value) {
  std::memcpy(p, &value, sizeof(T));
  p += sizeof(T);
}

template <typename T>
T get(const char* p) {
  T value;
  std::memcpy(&value, p, sizeof(T));
  return value;
}

IoError pcd_error(const std::string& path, const std::string& problem) {
  return IoError("PCD file '" + path + "': " + problem);
}

}  // namespace

size_t write_pcd(const std::string& path, const Scan& scan) {
  const size_t points = scan.point_count();
  std::vector<uint8_t> data(points * kPointSize);
  uint8_t* p = data.data();
  for (int ret = 0; ret < scan.returns; ++ret) {
    for (int ring = 0; ring < scan.rings; ++ring) {
      for (int col = 0; col < scan.columns; ++col) {
        const size_t i = scan.at(ret, ring, col);
        if (!scan.valid(i)) continue;
        put(p, scan.x[i]);
        put(p, scan.y[i]);
        put(p, scan.z[i]);
        put(p, static_cast<float>(scan.intensity[i]));
        put(p, static_cast<uint16_t>(ring));
        put(p, scan.azimuth_deg[i]);
        put(p, scan.time_s[i]);
        put(p, static_cast<uint8_t>(scan.return_type[i]));
      }
    }
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw IoError("cannot create PCD file '" + path + "'");
  out << "# .PCD v0.7 - Point Cloud Data file format\n"
      << "VERSION 0.7\n"
      << "FIELDS x y z intensity ring azimuth time return_type\n"
      << "SIZE 4 4 4 4 2 4 4 1\n"
      << "TYPE F F F F U F F U\n"
      << "COUNT 1 1 1 1 1 1 1 1\n"
      << "WIDTH " << points << "\n"
      << "HEIGHT 1\n"
      << "VIEWPOINT 0 0 0 1 0 0 0\n"
      << "POINTS " << points << "\n"
      << "DATA binary\n";
  out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
  out.close();
  if (!out) throw IoError("cannot write PCD file '" + path + "'");
  return points;
}

bool PcdCloud::has(const std::string& name) const {
  return std::find(fields.begin(), fields.end(), name) != fields.end();
}

const std::vector<double>& PcdCloud::field(const std::string& name) const {
  const auto it = std::find(fields.begin(), fields.end(), name);
  if (it == fields.end()) throw IoError("PCD cloud has no field '" + name + "'");
  return columns[static_cast<size_t>(it - fields.begin())];
}

PcdCloud read_pcd(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw pcd_error(path, "cannot open");
  PcdCloud cloud;
  std::vector<size_t> sizes, counts;
  std::vector<char> types;
  size_t points = 0;
  bool have_points = false;
  std::string data_kind;
  std::string line;
  while (data_kind.empty()) {
    if (!std::getline(in, line)) throw pcd_error(path, "header ends before DATA");
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    std::istringstream words(line);
    std::string key;
    words >> key;
    if (key == "FIELDS") {
      for (std::string f; words >> f;) cloud.fields.push_back(f);
    } else if (key == "SIZE") {
      for (size_t s; words >> s;) sizes.push_back(s);
    } else if (key == "TYPE") {
      for (std::string t; words >> t;) types.push_back(t.empty() ? '?' : t[0]);
    } else if (key == "COUNT") {
      for (size_t c; words >> c;) counts.push_back(c);
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
  const size_t n_fields = cloud.fields.size();
  if (n_fields == 0) throw pcd_error(path, "no FIELDS");
  if (sizes.size() != n_fields || types.size() != n_fields) {
    throw pcd_error(path, "FIELDS, SIZE and TYPE disagree in length");
  }
  if (counts.empty()) counts.assign(n_fields, 1);
  if (counts.size() != n_fields) throw pcd_error(path, "COUNT disagrees with FIELDS in length");
  if (cloud.height == 0) cloud.height = 1;
  // WIDTH x HEIGHT must not wrap around: 2^32 x 2^32 would read as an empty cloud.
  if (cloud.width > std::numeric_limits<size_t>::max() / cloud.height) {
    throw pcd_error(path, "WIDTH x HEIGHT (" + std::to_string(cloud.width) + " x " +
                              std::to_string(cloud.height) + ") is out of range");
  }
  if (!have_points) points = cloud.width * cloud.height;
  if (points != cloud.width * cloud.height) throw pcd_error(path, "POINTS is not WIDTH x HEIGHT");
  size_t point_size = 0;
  for (size_t f = 0; f < n_fields; ++f) {
    if (counts[f] != 1) throw pcd_error(path, "field '" + cloud.fields[f] + "' has COUNT != 1");
    const char t = types[f];
    const size_t s = sizes[f];
    const bool ok = (t == 'F' && (s == 4 || s == 8)) ||
                    ((t == 'U' || t == 'I') && (s == 1 || s == 2 || s == 4 || s == 8));
    if (!ok) {
      throw pcd_error(path, "field '" + cloud.fields[f] + "' has unsupported type " +
                                std::string(1, t) + std::to_string(s));
    }
    point_size += s;
  }
  if (data_kind != "ascii" && data_kind != "binary") {
    throw pcd_error(path, "DATA " + data_kind + " not supported (ascii or binary)");
  }
  // A corrupt header must not make us allocate more than the file could hold.
  const std::streamoff here = in.tellg();
  in.seekg(0, std::ios::end);
  const auto remaining = static_cast<size_t>(std::max<std::streamoff>(0, in.tellg() - here));
  in.seekg(here);
  const size_t min_bytes_per_point = data_kind == "ascii" ? 2 * n_fields : point_size;
  if (points > remaining / min_bytes_per_point + 1) {
    throw pcd_error(path, std::to_string(points) + " points cannot fit in the " +
                              std::to_string(remaining) + " bytes of data");
  }
  cloud.columns.assign(n_fields, std::vector<double>(points));

  if (data_kind == "ascii") {
    // Word by word with from_chars: istream's >> refuses the "nan" that PCL writes for
    // invalid points, and would call that the end of the data.
    std::string word;
    for (size_t i = 0; i < points; ++i) {
      for (size_t f = 0; f < n_fields; ++f) {
        if (!(in >> word)) throw pcd_error(path, "ascii data ends at point " + std::to_string(i));
        double& v = cloud.columns[f][i];
        const char* end = word.data() + word.size();
        const char* begin = word.data() + (word.size() > 1 && word[0] == '+' ? 1 : 0);
        const auto [p, ec] = std::from_chars(begin, end, v);
        if (ec != std::errc() || p != end) {
          throw pcd_error(path, "ascii value '" + word + "' of field '" + cloud.fields[f] +
                                    "' at point " + std::to_string(i) + " is not a number");
        }
      }
    }
  } else {
    std::vector<char> data(points * point_size);
    in.read(data.data(), static_cast<std::streamsize>(data.size()));
    if (static_cast<size_t>(in.gcount()) != data.size()) {
      throw pcd_error(path, "binary data holds " + std::to_string(in.gcount()) + " of " +
                                std::to_string(data.size()) + " bytes");
    }
    const char* p = data.data();
    for (size_t i = 0; i < points; ++i) {
      for (size_t f = 0; f < n_fields; ++f) {
        double& v = cloud.columns[f][i];
        switch (types[f]) {
          case 'F':
            v = sizes[f] == 4 ? get<float>(p) : get<double>(p);
            break;
          case 'U':
            v = sizes[f] == 1   ? get<uint8_t>(p)
                : sizes[f] == 2 ? get<uint16_t>(p)
                : sizes[f] == 4 ? get<uint32_t>(p)
                                : static_cast<double>(get<uint64_t>(p));
            break;
          default:
            v = sizes[f] == 1   ? get<int8_t>(p)
                : sizes[f] == 2 ? get<int16_t>(p)
                : sizes[f] == 4 ? get<int32_t>(p)
                                : static_cast<double>(get<int64_t>(p));
            break;
        }
        p += sizes[f];
      }
    }
  }
  return cloud;
}

}  // namespace lidartag::velodyne
