#include "lidartag/draw/units.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <stdexcept>

namespace lidartag::draw {
namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

// A positive finite number at the start of `s`; the rest is left in `s`.
std::optional<double> take_number(std::string_view& s) {
  double v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || !std::isfinite(v)) return std::nullopt;
  s.remove_prefix(static_cast<size_t>(end - s.data()));
  return v;
}

// Millimetres per unit, or nullopt for an unknown unit; `bare` for no unit.
std::optional<double> unit_mm(std::string_view unit, double bare) {
  const std::string u = lower(trim(unit));
  if (u.empty()) return bare;
  if (u == "m") return 1000.0;
  if (u == "cm") return 10.0;
  if (u == "mm") return 1.0;
  if (u == "in" || u == "\"" || u == "inch" || u == "inches") return 25.4;
  return std::nullopt;
}

}  // namespace

double parse_length_mm(std::string_view text) {
  std::string_view s = trim(text);
  const auto v = take_number(s);
  const auto unit = unit_mm(s, 1000.0);
  if (!v || !unit || *v <= 0)
    throw std::invalid_argument("'" + std::string(text) +
                                "' is not a length (a positive number with m, cm, mm or in; "
                                "metres without a unit)");
  return *v * *unit;
}

const std::vector<PaperSize>& named_paper_sizes() {
  static const std::vector<PaperSize> sizes = {
      {"A5", 148, 210},         {"A4", 210, 297},        {"A3", 297, 420},
      {"A2", 420, 594},         {"A1", 594, 841},        {"A0", 841, 1189},
      {"Letter", 215.9, 279.4}, {"Legal", 215.9, 355.6}, {"Tabloid", 279.4, 431.8}};
  return sizes;
}

std::string paper_size_names() {
  std::string out;
  for (const auto& p : named_paper_sizes()) out += (out.empty() ? "" : ", ") + p.name;
  return out;
}

PaperSize parse_paper_size(std::string_view text) {
  const std::string l = lower(trim(text));
  for (const auto& p : named_paper_sizes())
    if (lower(p.name) == l) return p;
  std::string_view s = l;
  const auto w = take_number(s);
  if (w && !s.empty() && s.front() == 'x') {
    s.remove_prefix(1);
    const auto h = take_number(s);
    const auto unit = unit_mm(s, 1.0);
    if (h && unit && *w > 0 && *h > 0) {
      PaperSize p;
      p.width_mm = *w * *unit;
      p.height_mm = *h * *unit;
      p.name = format_number(p.width_mm, 2) + "x" + format_number(p.height_mm, 2) + " mm";
      return p;
    }
  }
  throw std::invalid_argument("unknown paper size '" + std::string(text) + "' (" +
                              paper_size_names() + ", or WxH in mm such as 600x900, or 24x36in)");
}

std::string format_number(double v, int decimals) {
  std::string s = fmt::format("{:.{}f}", v, decimals);
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  return s == "-0" ? "0" : s;
}

std::string format_mm(double mm) {
  return format_number(mm, 2) + " mm";
}

std::string format_m(double mm) {
  return format_number(mm / 1000.0, 6);
}

}  // namespace lidartag::draw
