#include "lidartag/calib/image_io.hpp"

// clang-format off
#include <cstdio>  // jpeglib.h needs FILE and size_t first
#include <jpeglib.h>
// clang-format on
#include <png.h>

#include <csetjmp>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

namespace lidartag::calib {
namespace {

std::vector<uint8_t> read_file(const std::string& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status))
    throw ImageError("cannot read image '" + path + "': no such file");
  if (!std::filesystem::is_regular_file(status))
    throw ImageError("cannot read image '" + path + "': not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ImageError("cannot read image '" + path + "'");
  std::vector<uint8_t> data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw ImageError("error reading image '" + path + "'");
  return data;
}

void write_file(const std::vector<uint8_t>& data, const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw ImageError("cannot write image '" + path + "'");
  out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
  out.close();
  if (!out) throw ImageError("error writing image '" + path + "'");
}

bool is_png(std::span<const uint8_t> d) {
  return d.size() >= 8 && png_sig_cmp(d.data(), 0, 8) == 0;
}
bool is_jpeg(std::span<const uint8_t> d) {
  return d.size() >= 3 && d[0] == 0xFF && d[1] == 0xD8 && d[2] == 0xFF;
}

void check_size(int64_t w, int64_t h, const std::string& name) {
  if (w <= 0 || h <= 0 || w * h > kMaxImagePixels)
    throw ImageError("image '" + name + "': size " + std::to_string(w) + "x" + std::to_string(h) +
                     " is empty or larger than the limit");
}

// libpng's simplified API: it keeps its setjmp/longjmp inside and reports errors in
// image.message, so no C++ object lives across a longjmp here.
void decode_png(std::span<const uint8_t> data, bool rgb, int& width, int& height,
                std::vector<uint8_t>& pixels, const std::string& name) {
  png_image image;
  std::memset(&image, 0, sizeof image);
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&image, data.data(), data.size()))
    throw ImageError("corrupt PNG '" + name + "': " + image.message);
  image.format = rgb ? PNG_FORMAT_RGB : PNG_FORMAT_GRAY;
  try {
    check_size(image.width, image.height, name);
    pixels.resize(PNG_IMAGE_SIZE(image));
  } catch (...) {
    png_image_free(&image);
    throw;
  }
  if (!png_image_finish_read(&image, nullptr, pixels.data(), 0, nullptr))
    throw ImageError("corrupt PNG '" + name + "': " + image.message);
  width = static_cast<int>(image.width);
  height = static_cast<int>(image.height);
}

struct JpegError {
  jpeg_error_mgr mgr;  // first: libjpeg's err pointer is cast back to JpegError
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

[[noreturn]] void jpeg_fail(j_common_ptr cinfo) {
  auto* err = reinterpret_cast<JpegError*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, err->message);
  std::longjmp(err->jump, 1);
}

// Warnings (level -1) are corrupt data that libjpeg would paper over (a truncated file is padded
// with grey): refused like errors. Trace messages (level >= 0) are ignored.
void jpeg_message(j_common_ptr cinfo, int level) {
  if (level < 0) jpeg_fail(cinfo);
}

// Returns an empty string on success, else libjpeg's message. Only C objects (cinfo, err) and
// objects made before setjmp (pixels, owned by the caller) live across the longjmp.
std::string decode_jpeg_c(std::span<const uint8_t> data, bool rgb, int& width, int& height,
                          std::vector<uint8_t>& pixels) {
  jpeg_decompress_struct cinfo;
  JpegError err;
  cinfo.err = jpeg_std_error(&err.mgr);
  err.mgr.error_exit = jpeg_fail;
  err.mgr.emit_message = jpeg_message;
  if (setjmp(err.jump)) {
    jpeg_destroy_decompress(&cinfo);
    return err.message[0] ? std::string(err.message) : std::string("unknown libjpeg error");
  }
  err.message[0] = '\0';
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, data.data(), static_cast<unsigned long>(data.size()));
  jpeg_read_header(&cinfo, TRUE);
  cinfo.out_color_space = rgb ? JCS_RGB : JCS_GRAYSCALE;
  jpeg_start_decompress(&cinfo);
  const int64_t w = cinfo.output_width, h = cinfo.output_height;
  if (w <= 0 || h <= 0 || w * h > kMaxImagePixels) {
    std::snprintf(err.message, sizeof err.message, "size %lldx%lld is empty or too large",
                  static_cast<long long>(w), static_cast<long long>(h));
    jpeg_destroy_decompress(&cinfo);
    return err.message;
  }
  const size_t channels = rgb ? 3 : 1;
  const size_t row = static_cast<size_t>(w) * channels;
  if (pixels.capacity() < row * static_cast<size_t>(h)) {
    // Too big to reserve: leave before allocating inside the setjmp region.
    jpeg_destroy_decompress(&cinfo);
    return "internal: buffer not reserved";
  }
  pixels.resize(row * static_cast<size_t>(h));
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW p = pixels.data() + row * cinfo.output_scanline;
    jpeg_read_scanlines(&cinfo, &p, 1);
  }
  jpeg_finish_decompress(&cinfo);
  width = static_cast<int>(w);
  height = static_cast<int>(h);
  jpeg_destroy_decompress(&cinfo);
  return {};
}

// Reads the header first (its size), reserves the pixels outside the setjmp region, decodes.
void decode_jpeg(std::span<const uint8_t> data, bool rgb, int& width, int& height,
                 std::vector<uint8_t>& pixels, const std::string& name) {
  int64_t w = 0, h = 0;
  {
    jpeg_decompress_struct cinfo;
    JpegError err;
    err.message[0] = '\0';
    cinfo.err = jpeg_std_error(&err.mgr);
    err.mgr.error_exit = jpeg_fail;
    err.mgr.emit_message = jpeg_message;
    if (setjmp(err.jump)) {
      jpeg_destroy_decompress(&cinfo);
      throw ImageError("corrupt JPEG '" + name + "': " + err.message);
    }
    jpeg_create_decompress(&cinfo);
    jpeg_mem_src(&cinfo, data.data(), static_cast<unsigned long>(data.size()));
    jpeg_read_header(&cinfo, TRUE);
    w = cinfo.image_width;
    h = cinfo.image_height;
    jpeg_destroy_decompress(&cinfo);
  }
  check_size(w, h, name);
  pixels.clear();
  pixels.reserve(static_cast<size_t>(w * h) * (rgb ? 3u : 1u));
  const std::string message = decode_jpeg_c(data, rgb, width, height, pixels);
  if (!message.empty()) throw ImageError("corrupt JPEG '" + name + "': " + message);
}

template <typename Image>
Image decode(std::span<const uint8_t> data, const std::string& name, bool rgb) {
  Image image;
  if (is_png(data))
    decode_png(data, rgb, image.width, image.height, image.pixels, name);
  else if (is_jpeg(data))
    decode_jpeg(data, rgb, image.width, image.height, image.pixels, name);
  else
    throw ImageError("image '" + name + "' is neither PNG nor JPEG");
  return image;
}

void encode_png(int width, int height, const std::vector<uint8_t>& pixels, bool rgb,
                const std::string& path) {
  check_size(width, height, path);
  const size_t channels = rgb ? 3 : 1;
  if (pixels.size() != static_cast<size_t>(width) * static_cast<size_t>(height) * channels)
    throw ImageError("image for '" + path + "': pixel buffer does not match its size");
  png_image image;
  std::memset(&image, 0, sizeof image);
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(width);
  image.height = static_cast<png_uint_32>(height);
  image.format = rgb ? PNG_FORMAT_RGB : PNG_FORMAT_GRAY;
  png_alloc_size_t size = 0;
  if (!png_image_write_to_memory(&image, nullptr, &size, 0, pixels.data(), 0, nullptr))
    throw ImageError("cannot encode PNG '" + path + "': " + image.message);
  std::vector<uint8_t> out(size);
  if (!png_image_write_to_memory(&image, out.data(), &size, 0, pixels.data(), 0, nullptr))
    throw ImageError("cannot encode PNG '" + path + "': " + image.message);
  out.resize(size);
  write_file(out, path);
}

}  // namespace

GrayImage decode_gray(std::span<const uint8_t> data, const std::string& name) {
  return decode<GrayImage>(data, name, false);
}
RgbImage decode_rgb(std::span<const uint8_t> data, const std::string& name) {
  return decode<RgbImage>(data, name, true);
}
GrayImage read_gray(const std::string& path) {
  return decode_gray(read_file(path), path);
}
RgbImage read_rgb(const std::string& path) {
  return decode_rgb(read_file(path), path);
}
void write_png(const GrayImage& image, const std::string& path) {
  encode_png(image.width, image.height, image.pixels, false, path);
}
void write_png(const RgbImage& image, const std::string& path) {
  encode_png(image.width, image.height, image.pixels, true, path);
}

}  // namespace lidartag::calib
