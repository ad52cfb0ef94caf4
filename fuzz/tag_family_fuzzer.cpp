// Fuzz target: a tag family JSON file (the form of apriltag_families.json) through
// load_family_file, then the decoder's dictionary built from it, as `detector.families: [FILE]`
// does. Checks: bad files throw FamilyError; a family accepted has a payload bit per code bit
// inside its border, code words of nbits bits, renders to total_width^2 cells, and four quarter
// turns give every code back.
#include <cstddef>
#include <cstdint>

#include "fuzz_util.hpp"
#include "lidartag/detector/rkhs_decoder.hpp"
#include "lidartag/detector/tag_family.hpp"

using namespace lidartag;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static fuzz::MemFile file;
  const std::string& path = file.write({data, size});
  tags::TagFamily family;
  try {
    family = tags::load_family_file(path);
  } catch (const tags::FamilyError&) {
    return 0;
  }
  fuzz::check(family.nbits > 0 && family.nbits <= 64, "nbits out of 1..64");
  fuzz::check(family.bit_x.size() == static_cast<size_t>(family.nbits) &&
                  family.bit_y.size() == static_cast<size_t>(family.nbits),
              "a payload position per bit");
  fuzz::check(family.total_width >= family.width_at_border && family.width_at_border > 2, "widths");
  fuzz::check(!family.codes.empty(), "a family without codes");
  for (size_t i = 0; i < family.bit_x.size(); ++i)
    fuzz::check(family.bit_x[i] >= 0 && family.bit_y[i] >= 0 &&
                    family.bit_x[i] + family.border_start() < family.total_width &&
                    family.bit_y[i] + family.border_start() < family.total_width,
                "a payload bit outside the marker");
  const uint64_t mask =
      family.nbits == 64 ? ~uint64_t{0} : (uint64_t{1} << family.nbits) - uint64_t{1};
  for (size_t i = 0; i < family.codes.size() && i < 64; ++i) {
    const uint64_t code = family.codes[i];
    fuzz::check((code & ~mask) == 0, "a code word wider than nbits");
    fuzz::check(family.rotate(code, 4) == code, "four quarter turns do not give the code back");
    const auto image = family.render(code);
    fuzz::check(image.size() == static_cast<size_t>(family.total_width) *
                                    static_cast<size_t>(family.total_width),
                "rendered image size");
  }
  // The decoder's tables, as the detector builds them for a configured family.
  const detector::RkhsDictionary dictionary(family);
  (void)dictionary;
  return 0;
}
