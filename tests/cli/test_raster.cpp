#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>

#include "raster.hpp"

#include <gtest/gtest.h>

#include <filesystem>

namespace mgcloth::cli {
namespace {

namespace fs = std::filesystem;

const Rgb kWhite{255, 255, 255}, kBlack{0, 0, 0}, kRed{220, 40, 40};

fs::path temp_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("mgcloth_image_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::uint32_t big_endian(const std::string& bytes, size_t at) {
  std::uint32_t v = 0;
  for (size_t k = 0; k < 4; ++k) v = (v << 8) | static_cast<unsigned char>(bytes[at + k]);
  return v;
}

TEST(Image, StartsWithTheBackgroundAndRejectsBadSizes) {
  const Image img(7, 3, kRed);
  EXPECT_EQ(img.width(), 7);
  EXPECT_EQ(img.height(), 3);
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 7; ++x) EXPECT_EQ(img.pixel(x, y), kRed);
  EXPECT_THROW(Image(0, 5), Error);
  EXPECT_THROW(Image(5, -1), Error);
  EXPECT_THROW(Image(1 << 15, 1 << 15), Error);
}

TEST(Image, LineCoversItsPixelsAndNothingFarAway) {
  Image img(40, 20);
  img.draw_line(5.0, 10.5, 35.0, 10.5, 1.0, kBlack);  // along the centres of row 10
  for (int x = 6; x < 35; ++x) {
    EXPECT_EQ(img.pixel(x, 10), kBlack) << x;
    EXPECT_EQ(img.pixel(x, 8), kWhite) << x;
    EXPECT_EQ(img.pixel(x, 12), kWhite) << x;
  }
  EXPECT_EQ(img.pixel(38, 10), kWhite);
  // Thicker lines cover more rows; a line half a pixel off row centres blends two rows (anti-aliasing).
  Image thick(40, 20);
  thick.draw_line(5.0, 10.5, 35.0, 10.5, 5.0, kBlack);
  for (int y = 9; y <= 11; ++y) EXPECT_EQ(thick.pixel(20, y), kBlack) << y;
  EXPECT_EQ(thick.pixel(20, 15), kWhite);
  Image aa(40, 20);
  aa.draw_line(5.0, 10.0, 35.0, 10.0, 1.0, kBlack);
  EXPECT_GT(aa.pixel(20, 9).r, 0);
  EXPECT_LT(aa.pixel(20, 9).r, 255);
  EXPECT_EQ(aa.pixel(20, 9), aa.pixel(20, 10));
  // Off-image and non-finite segments are clipped or ignored, never written out of bounds.
  img.draw_line(-100.0, -100.0, 1000.0, 1000.0, 3.0, kRed);
  img.draw_line(0.0, 0.0, std::nan(""), 1.0, 3.0, kRed);
}

TEST(Image, CircleFillsItsDisk) {
  Image img(30, 30);
  img.fill_circle(15.0, 15.0, 5.0, kRed);
  EXPECT_EQ(img.pixel(15, 15), kRed);
  EXPECT_EQ(img.pixel(17, 13), kRed);
  EXPECT_EQ(img.pixel(15, 22), kWhite);
  EXPECT_EQ(img.pixel(2, 2), kWhite);
}

TEST(Image, TextUsesTheBuiltInFont) {
  Image img(64, 16);
  const int w = img.draw_text(1, 1, "L0 42", 2, kBlack);
  EXPECT_EQ(w, Image::text_width("L0 42", 2));
  EXPECT_EQ(w, (5 * 4 - 1) * 2);
  // 'L': the left column is ink, the top-right is not.
  EXPECT_EQ(img.pixel(1, 1), kBlack);
  EXPECT_EQ(img.pixel(1, 9), kBlack);
  EXPECT_EQ(img.pixel(5, 1), kWhite);
  // Nothing below the 5-row glyphs.
  for (int x = 0; x < 64; ++x) EXPECT_EQ(img.pixel(x, 12), kWhite) << x;
}

TEST(Image, PngRoundTripsThroughLibpng) {
  const fs::path dir = temp_dir("round_trip");
  Image img(37, 23);
  img.draw_line(2.0, 3.0, 30.0, 20.0, 2.5, Rgb{30, 90, 200});
  img.fill_circle(10.0, 15.0, 4.0, kRed);
  img.set_pixel(36, 22, Rgb{1, 2, 3});
  const fs::path file = dir / "sub" / "img.png";
  img.write_png(file);

  const std::string bytes = read_file(file);
  ASSERT_GE(bytes.size(), 33u);
  EXPECT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  EXPECT_EQ(bytes.substr(12, 4), "IHDR");
  EXPECT_EQ(big_endian(bytes, 16), 37u);
  EXPECT_EQ(big_endian(bytes, 20), 23u);
  EXPECT_EQ(bytes[24], 8);  // bit depth
  EXPECT_EQ(bytes[25], 2);  // colour type RGB

  const Image back = Image::read_png(file);
  EXPECT_EQ(back.width(), 37);
  EXPECT_EQ(back.height(), 23);
  EXPECT_EQ(back.data(), img.data());
  // Written atomically: no temporary left beside it.
  for (const auto& e : fs::directory_iterator(dir / "sub")) EXPECT_EQ(e.path().filename(), "img.png");
  fs::remove_all(dir);
}

TEST(Image, ReadingANonPngNamesTheFile) {
  const fs::path dir = temp_dir("bad");
  write_file_atomic(dir / "not.png", "hello");
  try {
    (void)Image::read_png(dir / "not.png");
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not.png"), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)Image::read_png(dir / "missing.png"), InputError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mgcloth::cli
