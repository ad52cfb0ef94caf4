#include "lidartag/detector/tag_family.hpp"

#include <bit>
#include <fstream>
#include <nlohmann/json.hpp>

#include "tag_family_data.hpp"

namespace lidartag::tags {
namespace {

TagFamily from_table(const data::FamilyTable& t) {
  TagFamily f;
  f.name = t.name;
  f.nbits = t.nbits;
  f.min_hamming = t.min_hamming;
  f.total_width = t.total_width;
  f.width_at_border = t.width_at_border;
  f.reversed_border = t.reversed_border;
  f.bit_x.assign(t.bit_x.begin(), t.bit_x.end());
  f.bit_y.assign(t.bit_y.begin(), t.bit_y.end());
  f.codes.assign(t.codes.begin(), t.codes.end());
  return f;
}

const std::vector<TagFamily>& builtins() {
  static const std::vector<TagFamily> all = [] {
    std::vector<TagFamily> v;
    for (size_t i = 0; i < data::kFamilyCount; ++i) v.push_back(from_table(data::kFamilies[i]));
    return v;
  }();
  return all;
}

// nlohmann's get<int>() of a float or an out-of-range number is an unchecked cast: a family file
// must give whole numbers in range.
int int_field(const nlohmann::json& v, const char* key) {
  constexpr int64_t kLimit = 1'000'000;
  const bool in_range =
      v.is_number_integer() &&
      (v.is_number_unsigned() ? v.get<uint64_t>() <= static_cast<uint64_t>(kLimit)
                              : v.get<int64_t>() >= -kLimit && v.get<int64_t>() <= kLimit);
  if (!in_range)
    throw FamilyError(std::string(key) + ": '" + v.dump() + "' is not a whole number in range");
  return static_cast<int>(v.get<int64_t>());
}

std::vector<int> int_list(const nlohmann::json& v, const char* key) {
  if (!v.is_array()) throw FamilyError(std::string(key) + ": expected a list of whole numbers");
  std::vector<int> out;
  for (const auto& e : v) out.push_back(int_field(e, key));
  return out;
}

uint64_t code_word(const nlohmann::json& c) {
  if (c.is_number_unsigned()) return c.get<uint64_t>();
  if (c.is_number_integer() && c.get<int64_t>() >= 0)
    return static_cast<uint64_t>(c.get<int64_t>());
  if (c.is_string()) {
    const std::string text = c.get<std::string>();
    size_t used = 0;
    uint64_t value = 0;
    try {
      value = std::stoull(text, &used, 0);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == text.size() && !text.empty() && text[0] != '-') return value;
  }
  throw FamilyError("codes: '" + c.dump() +
                    "' is not a code word (an unsigned integer or a string "
                    "such as \"0x27c8\")");
}

void validate(const TagFamily& f, const std::string& where) {
  auto fail = [&](const std::string& why) { throw FamilyError(where + ": " + why); };
  if (f.nbits <= 0 || f.nbits > 64) fail("nbits must be 1..64");
  if (f.reversed_border) fail("reversed-border families are not supported");
  if (f.total_width != f.width_at_border + 2) fail("total_width must be width_at_border + 2");
  const int pw = f.payload_width();
  if (pw <= 0 || pw * pw != f.nbits) fail("nbits must fill a square payload inside the border");
  if (static_cast<int>(f.bit_x.size()) != f.nbits || static_cast<int>(f.bit_y.size()) != f.nbits)
    fail("bit_x and bit_y need nbits entries");
  for (int i = 0; i < f.nbits; ++i) {
    const auto ui = static_cast<size_t>(i);
    if (f.bit_x[ui] < 1 || f.bit_x[ui] > pw || f.bit_y[ui] < 1 || f.bit_y[ui] > pw)
      fail("bit " + std::to_string(i) + " lies outside the payload");
  }
  if (f.codes.empty()) fail("no codes");
  const uint64_t mask = f.nbits == 64 ? ~0ULL : ((1ULL << f.nbits) - 1);
  for (uint64_t c : f.codes)
    if (c & ~mask) fail("a code has more than nbits bits");
}

}  // namespace

std::vector<uint8_t> TagFamily::render(uint64_t code) const {
  const auto w = static_cast<size_t>(total_width);
  std::vector<uint8_t> img(w * w, 1);
  for (size_t r = 1; r + 1 < w; ++r)
    for (size_t c = 1; c + 1 < w; ++c) img[r * w + c] = 0;
  const int b = border_start();
  for (int i = 0; i < nbits; ++i) {
    const auto ui = static_cast<size_t>(i);
    const bool white = (code >> (nbits - 1 - i)) & 1ULL;
    const auto row = static_cast<size_t>(bit_y[ui] + b);
    const auto col = static_cast<size_t>(bit_x[ui] + b);
    img[row * w + col] = white ? 1 : 0;
  }
  return img;
}

uint64_t TagFamily::rotate(uint64_t code, int quarter_turns) const {
  const int pw = payload_width();
  const int b = border_start();
  uint64_t out = code;
  for (int q = 0; q < ((quarter_turns % 4) + 4) % 4; ++q) {
    uint64_t next = 0;
    // Clockwise turn of the image: the cell at (row, col) moves to (col, W-1-row).
    for (int i = 0; i < nbits; ++i) {
      const auto ui = static_cast<size_t>(i);
      const int row = bit_y[ui] - 1, col = bit_x[ui] - 1;  // payload coordinates
      const int nrow = col, ncol = pw - 1 - row;
      for (int j = 0; j < nbits; ++j) {
        const auto uj = static_cast<size_t>(j);
        if (bit_y[uj] - 1 == nrow && bit_x[uj] - 1 == ncol) {
          if ((out >> (nbits - 1 - i)) & 1ULL) next |= 1ULL << (nbits - 1 - j);
          break;
        }
      }
    }
    out = next;
  }
  (void)b;
  return out;
}

int TagFamily::measured_min_hamming() const {
  int best = nbits;
  for (size_t i = 0; i < codes.size(); ++i) {
    for (int q = 1; q < 4; ++q) {  // a code against its own rotations
      const int d = std::popcount(codes[i] ^ rotate(codes[i], q));
      best = std::min(best, d);
    }
    for (size_t j = i + 1; j < codes.size(); ++j)
      for (int q = 0; q < 4; ++q)
        best = std::min(best, std::popcount(codes[i] ^ rotate(codes[j], q)));
  }
  return best;
}

const TagFamily& builtin_family(std::string_view name) {
  for (const auto& f : builtins())
    if (f.name == name) return f;
  std::string known;
  for (const auto& f : builtins()) known += (known.empty() ? "" : ", ") + f.name;
  throw FamilyError("unknown tag family '" + std::string(name) + "' (built in: " + known +
                    "; or give FILE.json[:NAME])");
}

std::vector<std::string> builtin_family_names() {
  std::vector<std::string> v;
  for (const auto& f : builtins()) v.push_back(f.name);
  return v;
}

TagFamily load_family_file(const std::string& path, std::string_view name) {
  std::ifstream in(path);
  if (!in) throw FamilyError("cannot open tag family file '" + path + "'");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw FamilyError("tag family file '" + path + "': " + e.what());
  }
  if (!j.is_object() || j.empty()) throw FamilyError("tag family file '" + path + "': no family");
  std::string key(name);
  if (key.empty()) {
    if (j.size() != 1)
      throw FamilyError("tag family file '" + path + "' holds several families: say FILE:NAME");
    key = j.begin().key();
  }
  if (!j.contains(key))
    throw FamilyError("tag family file '" + path + "' has no family '" + key + "'");
  const auto& o = j[key];
  TagFamily f;
  f.name = key;
  try {
    if (!o.is_object()) throw FamilyError("expected an object with nbits, codes, ...");
    f.nbits = int_field(o.at("nbits"), "nbits");
    // Unknown (null or absent) for some published sets.
    f.min_hamming = o.contains("min_hamming") && !o["min_hamming"].is_null()
                        ? int_field(o["min_hamming"], "min_hamming")
                        : 0;
    f.total_width = int_field(o.at("total_width"), "total_width");
    f.width_at_border = int_field(o.at("width_at_border"), "width_at_border");
    f.reversed_border = o.value("reversed_border", false);
    f.bit_x = int_list(o.at("bit_x"), "bit_x");
    f.bit_y = int_list(o.at("bit_y"), "bit_y");
    if (!o.at("codes").is_array()) throw FamilyError("codes: expected a list");
    for (const auto& c : o.at("codes")) f.codes.push_back(code_word(c));
  } catch (const std::exception& e) {
    throw FamilyError("tag family '" + key + "' in '" + path + "': " + e.what());
  }
  validate(f, "tag family '" + key + "' in '" + path + "'");
  return f;
}

TagFamily resolve_family(const std::string& name_or_path) {
  for (const auto& f : builtins())
    if (f.name == name_or_path) return f;
  const auto json = name_or_path.find(".json");
  if (json == std::string::npos) return builtin_family(name_or_path);  // throws, listing names
  const std::string path = name_or_path.substr(0, json + 5);
  std::string name;
  if (json + 5 < name_or_path.size() && name_or_path[json + 5] == ':')
    name = name_or_path.substr(json + 6);
  return load_family_file(path, name);
}

}  // namespace lidartag::tags
