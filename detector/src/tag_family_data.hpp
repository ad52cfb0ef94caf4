// Raw family tables (generated data in tag_family_data.cpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace lidartag::tags::data {

struct FamilyTable {
  const char* name;
  int nbits;
  int min_hamming;  // 0 when not published
  int total_width;
  int width_at_border;
  bool reversed_border;
  std::span<const uint64_t> codes;
  std::span<const uint8_t> bit_x;
  std::span<const uint8_t> bit_y;
};

extern const FamilyTable kFamilies[];
extern const size_t kFamilyCount;

}  // namespace lidartag::tags::data
