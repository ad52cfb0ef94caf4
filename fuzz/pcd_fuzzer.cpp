// Fuzz target: a PCD file through read_pcd (ascii, binary and binary_compressed, any header).
// Checks: bad files throw IoError naming the problem; a cloud read has one column per field, each
// of width x height numbers, no more points than the file's bytes can hold, and every field name
// can be looked up.
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
  return 0;
}
