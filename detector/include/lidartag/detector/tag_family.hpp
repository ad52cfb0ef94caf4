// AprilTag-style families as data: code words and the cell layout of the printed marker.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace lidartag::tags {

// Setup error: unknown family, unreadable or malformed family file.
class FamilyError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct TagFamily {
  std::string name;
  int nbits = 0;
  int min_hamming = 0;      // as published, 0 when unknown
  int total_width = 0;      // cells across the whole marker (white ring included)
  int width_at_border = 0;  // cells across the black border square
  bool reversed_border = false;
  std::vector<int> bit_x, bit_y;  // payload bit i (MSB first) sits at (bit_x + border_start, ...)
  std::vector<uint64_t> codes;

  int border_start() const { return (total_width - width_at_border) / 2; }
  // Payload cells across (d in the paper: 4 for 16-bit families).
  int payload_width() const { return width_at_border - 2; }
  int ncodes() const { return static_cast<int>(codes.size()); }

  // The printed image of `code`: total_width x total_width cells, row-major, row 0 at the top of
  // the image, column 0 at its left; 1 = white, 0 = black.
  std::vector<uint8_t> render(uint64_t code) const;
  // The code word read after rotating the printed image by 90 degrees clockwise, `quarter_turns`
  // times (a permutation of payload bits).
  uint64_t rotate(uint64_t code, int quarter_turns) const;
  // Smallest Hamming distance between two different codes over all 4 rotations (measured).
  int measured_min_hamming() const;
};

// Built-in families: tag16h5 (default), tag25h9, tag36h10, tag36h11, tag16h6 (the LiDARTag
// paper's 9 markers). Throws FamilyError for an unknown name.
const TagFamily& builtin_family(std::string_view name);
std::vector<std::string> builtin_family_names();

// A family from a JSON file of the form of apriltag_families.json: an object whose keys are family
// names. Loads `name`, or the only family in the file when `name` is empty. Throws FamilyError.
TagFamily load_family_file(const std::string& path, std::string_view name = {});
// Looks `name_or_path` up among the built-in families, else treats it as "FILE.json[:NAME]".
TagFamily resolve_family(const std::string& name_or_path);

}  // namespace lidartag::tags
