// Lengths and paper sizes as a user types them: "1.2m", "200mm", "8in"; "A4", "Letter",
// "600x900", "24x36in". Everything is returned in millimetres.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lidartag::draw {

// A length with an optional unit: m, cm, mm, in (or "); a bare number is metres (as --tag-size).
// Throws std::invalid_argument with a message naming the text.
double parse_length_mm(std::string_view text);

struct PaperSize {
  std::string name;                    // "A4", "Letter", or "600x900 mm" for a custom size
  double width_mm = 0, height_mm = 0;  // portrait: width <= height for the named sizes
};

// The named sizes, smallest first: A5..A0 (ISO 216), Letter, Legal, Tabloid (ANSI).
const std::vector<PaperSize>& named_paper_sizes();
// "A4" (any case), or "WxH" with an optional unit after H (mm by default, "in", "cm"), e.g.
// "600x900", "24x36in". Throws std::invalid_argument.
PaperSize parse_paper_size(std::string_view text);
// "A0, A1, ..., Tabloid" for help texts.
std::string paper_size_names();

// `v` with at most `decimals` decimals, trailing zeros dropped: "12.5", "1200", "0.1625".
std::string format_number(double v, int decimals);
// "1200 mm", "12.5 mm", "0.35 mm": millimetres without trailing zeros (at most 2 decimals).
std::string format_mm(double mm);
// Metres as a user would type them for --tag-size: "1.2", "0.1625".
std::string format_m(double mm);

}  // namespace lidartag::draw
