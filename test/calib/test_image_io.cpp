// Image I/O: PNG and JPEG read back what was written; corrupt, truncated and foreign files are
// refused with ImageError naming the file, never a crash.
#include <gtest/gtest.h>

// clang-format off
#include <cstdio>
#include <jpeglib.h>
// clang-format on

#include <filesystem>
#include <fstream>

#include "lidartag/calib/image_io.hpp"

namespace lidartag::calib {
namespace {

std::string temp_path(const std::string& name) {
  return (std::filesystem::path(::testing::TempDir()) / ("image_io_" + name)).string();
}

std::vector<uint8_t> slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void spit(const std::vector<uint8_t>& data, const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
}

GrayImage gradient(int w, int h) {
  GrayImage g(w, h);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) g.at(u, v) = static_cast<uint8_t>((u * 7 + v * 13) % 256);
  return g;
}

// A JPEG of a grey or RGB image by libjpeg (test data only).
std::vector<uint8_t> encode_jpeg(int w, int h, const std::vector<uint8_t>& pixels, bool rgb,
                                 int quality) {
  jpeg_compress_struct c;
  jpeg_error_mgr err;
  c.err = jpeg_std_error(&err);
  jpeg_create_compress(&c);
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  jpeg_mem_dest(&c, &buffer, &size);
  c.image_width = static_cast<JDIMENSION>(w);
  c.image_height = static_cast<JDIMENSION>(h);
  c.input_components = rgb ? 3 : 1;
  c.in_color_space = rgb ? JCS_RGB : JCS_GRAYSCALE;
  jpeg_set_defaults(&c);
  jpeg_set_quality(&c, quality, TRUE);
  jpeg_start_compress(&c, TRUE);
  const size_t row = static_cast<size_t>(w) * (rgb ? 3u : 1u);
  while (c.next_scanline < c.image_height) {
    auto* p = const_cast<JSAMPLE*>(pixels.data() + row * c.next_scanline);
    jpeg_write_scanlines(&c, &p, 1);
  }
  jpeg_finish_compress(&c);
  std::vector<uint8_t> out(buffer, buffer + size);
  jpeg_destroy_compress(&c);
  std::free(buffer);
  return out;
}

TEST(ImageIo, GrayPngRoundTripsExactly) {
  const GrayImage g = gradient(37, 23);
  const std::string path = temp_path("gray.png");
  write_png(g, path);
  const GrayImage back = read_gray(path);
  EXPECT_EQ(back.width, 37);
  EXPECT_EQ(back.height, 23);
  EXPECT_EQ(back.pixels, g.pixels);
}

TEST(ImageIo, RgbPngRoundTripsExactlyAndReadsAsGray) {
  RgbImage c;
  c.width = 5;
  c.height = 4;
  for (int i = 0; i < 20; ++i) {
    c.pixels.push_back(static_cast<uint8_t>(i * 10));
    c.pixels.push_back(static_cast<uint8_t>(255 - i * 10));
    c.pixels.push_back(static_cast<uint8_t>(i % 2 ? 255 : 0));
  }
  // A grey RGB pixel (equal channels) must stay that grey when read as grey.
  c.pixels[0] = c.pixels[1] = c.pixels[2] = 77;
  const std::string path = temp_path("rgb.png");
  write_png(c, path);
  const RgbImage back = read_rgb(path);
  EXPECT_EQ(back.pixels, c.pixels);
  const GrayImage g = read_gray(path);
  ASSERT_EQ(g.width, 5);
  EXPECT_NEAR(g.at(0, 0), 77, 1);
}

TEST(ImageIo, GrayPngReadsAsRgbWithEqualChannels) {
  const GrayImage g = gradient(8, 3);
  const std::string path = temp_path("g2rgb.png");
  write_png(g, path);
  const RgbImage c = read_rgb(path);
  ASSERT_EQ(c.pixels.size(), 3u * 8 * 3);
  for (size_t i = 0; i < g.pixels.size(); ++i) {
    EXPECT_EQ(c.pixels[3 * i], g.pixels[i]);
    EXPECT_EQ(c.pixels[3 * i + 2], g.pixels[i]);
  }
}

TEST(ImageIo, JpegReadsCloseToItsSource) {
  GrayImage g(64, 48);
  for (int v = 0; v < 48; ++v)
    for (int u = 0; u < 64; ++u) g.at(u, v) = static_cast<uint8_t>(u * 4);  // smooth ramp
  const std::string path = temp_path("gray.jpg");
  spit(encode_jpeg(64, 48, g.pixels, false, 95), path);
  const GrayImage back = read_gray(path);
  ASSERT_EQ(back.width, 64);
  ASSERT_EQ(back.height, 48);
  int worst = 0;
  for (size_t i = 0; i < g.pixels.size(); ++i)
    worst = std::max(worst, std::abs(int(back.pixels[i]) - int(g.pixels[i])));
  EXPECT_LE(worst, 4);
  const RgbImage c = read_rgb(path);
  EXPECT_EQ(c.pixels.size(), 3u * 64 * 48);
}

TEST(ImageIo, ColourJpegReadsAsItsLuma) {
  std::vector<uint8_t> rgb;
  for (int i = 0; i < 32 * 32; ++i) {
    rgb.push_back(200);
    rgb.push_back(100);
    rgb.push_back(50);
  }
  const std::string path = temp_path("rgb.jpg");
  spit(encode_jpeg(32, 32, rgb, true, 95), path);
  const GrayImage g = read_gray(path);
  // Y = 0.299 R + 0.587 G + 0.114 B = 124.
  EXPECT_NEAR(g.at(16, 16), 124, 3);
  const RgbImage c = read_rgb(path);
  EXPECT_NEAR(c.pixels[0], 200, 4);
}

void expect_refused(const std::string& path, const std::string& what) {
  try {
    (void)read_gray(path);
    FAIL() << "no exception for " << path;
  } catch (const ImageError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(path), std::string::npos) << m;
    EXPECT_NE(m.find(what), std::string::npos) << m;
  }
}

TEST(ImageIo, TruncatedPngIsRefused) {
  const std::string path = temp_path("t.png");
  write_png(gradient(64, 64), path);
  std::vector<uint8_t> d = slurp(path);
  for (size_t keep : {size_t{8}, size_t{40}, d.size() / 2, d.size() - 13}) {
    spit(std::vector<uint8_t>(d.begin(), d.begin() + static_cast<long>(keep)), path);
    expect_refused(path, "corrupt PNG");
  }
}

TEST(ImageIo, CorruptPngIsRefused) {
  const std::string path = temp_path("c.png");
  write_png(gradient(64, 64), path);
  std::vector<uint8_t> d = slurp(path);
  for (size_t i = 60; i < d.size() - 20; ++i) d[i] ^= 0x5A;  // the image data, CRCs now wrong
  spit(d, path);
  expect_refused(path, "corrupt PNG");
}

TEST(ImageIo, TruncatedJpegIsRefusedNotPadded) {
  GrayImage g = gradient(64, 64);
  const std::vector<uint8_t> d = encode_jpeg(64, 64, g.pixels, false, 90);
  const std::string path = temp_path("t.jpg");
  for (size_t keep : {size_t{3}, size_t{100}, d.size() / 2, d.size() - 2}) {
    spit(std::vector<uint8_t>(d.begin(), d.begin() + static_cast<long>(keep)), path);
    expect_refused(path, "corrupt JPEG");
  }
}

TEST(ImageIo, GarbageAndMissingFilesAreRefused) {
  const std::string path = temp_path("garbage.png");
  spit({'h', 'e', 'l', 'l', 'o', ' ', 'w', 'o', 'r', 'l', 'd'}, path);
  expect_refused(path, "neither PNG nor JPEG");
  spit({}, path);
  expect_refused(path, "neither PNG nor JPEG");
  expect_refused(temp_path("does_not_exist.png"), "no such file");
  expect_refused(::testing::TempDir(), "not a regular file");
}

TEST(ImageIo, WriteRefusesMismatchedBufferAndBadPath) {
  GrayImage g(4, 4);
  g.pixels.pop_back();
  EXPECT_THROW(write_png(g, temp_path("bad.png")), ImageError);
  EXPECT_THROW(write_png(gradient(4, 4), "/nonexistent-dir/x.png"), ImageError);
}

}  // namespace
}  // namespace lidartag::calib
