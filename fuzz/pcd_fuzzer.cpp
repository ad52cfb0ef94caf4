// Fuzz target: a PCD file through read_pcd (ascii, binary and binary_compressed, any header).
// Checks: bad files throw IoError naming the problem; a cloud read has one column per field, each
// of width x height numbers, no more points than the file's bytes can hold, and every field name
// can be looked up; the cloud's columns by the field vocabulary bags share (pcd_cloud_columns) are
// of the cloud's size, named only as that vocabulary names them, their times finite or not there.
#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "fuzz_util.hpp"
#include "lidartag/driver/io/errors.hpp"
#include "lidartag/driver/velodyne/io/pcd.hpp"

using namespace lidartag;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static fuzz::MemFile file;
  const std::string& path = file.write({data, size});
  velodyne::PcdCloud cloud;
  try {
    cloud = velodyne::read_pcd(path);
  } catch (const driver::IoError&) {
    return 0;
  }
  fuzz::check(cloud.columns.size() == cloud.fields.size(), "columns != fields");
  // Every point takes at least one byte of the file (binary) or one character (ascii). LZF unpacks
  // to at most 88 times its size (a 3-byte back reference gives at most 264 bytes), so a
  // compressed file holds at most 88 one-byte points per byte: 2,000 zero floats fit in 241 bytes.
  const size_t per_byte = cloud.format == velodyne::PcdFormat::kBinaryCompressed ? 88 : 1;
  fuzz::check(cloud.fields.empty() || cloud.size() <= per_byte * size, "more points than bytes");
  for (size_t f = 0; f < cloud.fields.size(); ++f) {
    fuzz::check(cloud.columns[f].size() == cloud.size(), "a column of the wrong length");
    fuzz::check(cloud.has(cloud.fields[f]), "a field that cannot be found");
    (void)cloud.field(cloud.fields[f]);
  }
  driver::CloudColumns columns;
  velodyne::pcd_cloud_columns(cloud, columns);
  fuzz::check(columns.names.size() == columns.columns.size() &&
                  columns.source.size() == columns.columns.size(),
              "columns, names and sources disagree");
  for (size_t c = 0; c < columns.columns.size(); ++c) {
    fuzz::check(columns.columns[c].size() == cloud.size(), "a named column of the wrong length");
    const std::string& name = columns.names[c];
    fuzz::check(name == "ring" || name == "time" ||
                    std::find(driver::kPlainFieldNames.begin(), driver::kPlainFieldNames.end(),
                              name) != driver::kPlainFieldNames.end(),
                "a column named outside the vocabulary");
  }
  return 0;
}
