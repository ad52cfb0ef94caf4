// Images in and out: PNG (libpng) and JPEG (libjpeg) read into 8-bit grey or RGB, PNG written.
// Row 0 is the top of the image; pixel (u, v) is pixels[v * width + u] (grey) or the three bytes
// from 3 * (v * width + u) (RGB), and its centre is at (u, v) in lidartag's pixel convention
// (camera_model.hpp). Setup-time code: errors are ImageError exceptions naming the file.
#pragma once

#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace lidartag::calib {

// A file that cannot be read or written, is neither PNG nor JPEG, or is corrupt or truncated.
class ImageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct GrayImage {
  int width = 0, height = 0;
  std::vector<uint8_t> pixels;  // width * height, row-major, 0 black .. 255 white

  GrayImage() = default;
  GrayImage(int w, int h, uint8_t value = 0)
      : width(w), height(h), pixels(static_cast<size_t>(w) * static_cast<size_t>(h), value) {}
  size_t index(int u, int v) const {
    return static_cast<size_t>(v) * static_cast<size_t>(width) + static_cast<size_t>(u);
  }
  uint8_t& at(int u, int v) { return pixels[index(u, v)]; }
  uint8_t at(int u, int v) const { return pixels[index(u, v)]; }
};

struct RgbImage {
  int width = 0, height = 0;
  std::vector<uint8_t> pixels;  // 3 * width * height, row-major, R G B per pixel
};

// Largest image accepted, in pixels (a 16k x 16k image): a corrupt header cannot ask for more.
inline constexpr int64_t kMaxImagePixels = int64_t{16384} * 16384;

// Reads a PNG or JPEG (told apart by their signatures, not the file name) as grey. Colour images
// are converted by the libraries (libpng: its sRGB-aware RGB -> grey; libjpeg: the luma Y of
// YCbCr); alpha is composited onto black; 16-bit samples are reduced to 8 bits. Throws ImageError
// for an unreadable file, an unknown format, a corrupt or truncated image (libjpeg's "premature
// end of data" warnings included: a truncated JPEG is refused, not padded with grey).
GrayImage read_gray(const std::string& path);
RgbImage read_rgb(const std::string& path);
// The same from bytes in memory; `name` names the data in error messages.
GrayImage decode_gray(std::span<const uint8_t> data, const std::string& name);
RgbImage decode_rgb(std::span<const uint8_t> data, const std::string& name);

// Writes an 8-bit PNG. Throws ImageError.
void write_png(const GrayImage& image, const std::string& path);
void write_png(const RgbImage& image, const std::string& path);

}  // namespace lidartag::calib
