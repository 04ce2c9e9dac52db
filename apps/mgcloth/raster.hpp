#pragma once
// Pictures drawn by the CLI itself, without a browser: the hierarchy levels of `mgcloth hierarchy`. The library
// draws nothing; this is the command-line tool's own.
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace mgcloth::cli {

/// An 8-bit RGB colour.
struct Rgb {
  std::uint8_t r = 0, g = 0, b = 0;
  bool operator==(const Rgb&) const = default;
};

/// A small software raster image (RGB8, row-major, origin top-left, y down) for diagnostic pictures such as the
/// hierarchy levels of `mgcloth hierarchy`. Shapes are drawn anti-aliased: a pixel is blended with the colour by
/// the fraction of it the shape covers, estimated from the distance of the pixel centre (x + 0.5, y + 0.5) to the
/// shape's outline (coverage = clamp(0.5 − signed distance, 0, 1)).
class Image {
 public:
  Image() = default;
  /// Throws Error for non-positive or huge sizes (more than 2^28 pixels).
  Image(int width, int height, Rgb background = {255, 255, 255});

  int width() const { return m_width; }
  int height() const { return m_height; }
  Rgb pixel(int x, int y) const;
  void set_pixel(int x, int y, Rgb c);
  /// c over the pixel with opacity alpha in [0, 1]; pixels outside the image are ignored.
  void blend_pixel(int x, int y, Rgb c, double alpha);
  void fill(Rgb c);
  /// Axis-aligned box [x0, x1) x [y0, y1), clipped; not anti-aliased.
  void fill_rect(int x0, int y0, int x1, int y1, Rgb c);

  /// A segment of the given thickness (pixels) with round caps, in continuous pixel coordinates.
  void draw_line(double x0, double y0, double x1, double y1, double thickness, Rgb c);
  void fill_circle(double cx, double cy, double radius, Rgb c);
  /// Text in a built-in 3x5 pixel font, each font pixel a `scale` x `scale` block; (x, y) is the top-left corner.
  /// Covers digits, upper-case letters (lower case is drawn as upper case), space and . , : - = ( ) / %;
  /// other characters are drawn as blanks. Returns the width drawn, in pixels.
  int draw_text(int x, int y, const std::string& text, int scale, Rgb c);
  /// The width draw_text would take.
  static int text_width(const std::string& text, int scale);

  /// The image as a PNG file (8-bit RGB, via libpng), in memory.
  std::vector<std::uint8_t> encode_png() const;
  /// Writes the PNG atomically (temporary file, then rename; see write_file_atomic). Throws Error naming the path.
  void write_png(const std::filesystem::path& path) const;
  /// Reads an 8-bit RGB(A)/grey PNG (alpha composed over white); throws InputError naming the path.
  static Image read_png(const std::filesystem::path& path);

  const std::vector<std::uint8_t>& data() const { return m_pixels; }

 private:
  int m_width = 0, m_height = 0;
  std::vector<std::uint8_t> m_pixels;  ///< 3 bytes per pixel, rows top to bottom
};

}  // namespace mgcloth::cli
