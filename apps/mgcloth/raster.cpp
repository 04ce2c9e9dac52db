#include "raster.hpp"

#include <mgcloth/core/error.hpp>
#include <mgcloth/core/file_io.hpp>

#include <png.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <string_view>

namespace mgcloth::cli {

namespace {

/// 3x5 glyphs, rows top to bottom, '1' = ink.
std::string_view glyph(char ch) {
  switch (std::toupper(static_cast<unsigned char>(ch))) {
    case '0': return "111101101101111";
    case '1': return "010110010010111";
    case '2': return "111001111100111";
    case '3': return "111001111001111";
    case '4': return "101101111001001";
    case '5': return "111100111001111";
    case '6': return "111100111101111";
    case '7': return "111001001001001";
    case '8': return "111101111101111";
    case '9': return "111101111001111";
    case 'A': return "010101111101101";
    case 'B': return "110101110101110";
    case 'C': return "011100100100011";
    case 'D': return "110101101101110";
    case 'E': return "111100110100111";
    case 'F': return "111100110100100";
    case 'G': return "011100101101011";
    case 'H': return "101101111101101";
    case 'I': return "111010010010111";
    case 'J': return "001001001101010";
    case 'K': return "101101110101101";
    case 'L': return "100100100100111";
    case 'M': return "101111111101101";
    case 'N': return "110101101101101";
    case 'O': return "010101101101010";
    case 'P': return "110101110100100";
    case 'Q': return "010101101110011";
    case 'R': return "110101110101101";
    case 'S': return "011100010001110";
    case 'T': return "111010010010010";
    case 'U': return "101101101101111";
    case 'V': return "101101101101010";
    case 'W': return "101101111111101";
    case 'X': return "101101010101101";
    case 'Y': return "101101010010010";
    case 'Z': return "111001010100111";
    case '.': return "000000000000010";
    case ',': return "000000000010100";
    case ':': return "000010000010000";
    case '-': return "000000111000000";
    case '=': return "000111000111000";
    case '(': return "001010010010001";
    case ')': return "100010010010100";
    case '/': return "001001010100100";
    case '%': return "101001010100101";
    default: return "000000000000000";
  }
}

double clamp01(double a) { return std::clamp(a, 0.0, 1.0); }

}  // namespace

Image::Image(int width, int height, Rgb background) : m_width(width), m_height(height) {
  if (width <= 0 || height <= 0 || static_cast<long long>(width) * height > (1LL << 28))
    throw_error("image: invalid size {} x {}", width, height);
  m_pixels.resize(3 * static_cast<size_t>(width) * height);
  fill(background);
}

Rgb Image::pixel(int x, int y) const {
  const size_t k = 3 * (static_cast<size_t>(y) * m_width + x);
  return {m_pixels[k], m_pixels[k + 1], m_pixels[k + 2]};
}

void Image::set_pixel(int x, int y, Rgb c) {
  if (x < 0 || y < 0 || x >= m_width || y >= m_height) return;
  const size_t k = 3 * (static_cast<size_t>(y) * m_width + x);
  m_pixels[k] = c.r;
  m_pixels[k + 1] = c.g;
  m_pixels[k + 2] = c.b;
}

void Image::blend_pixel(int x, int y, Rgb c, double alpha) {
  if (x < 0 || y < 0 || x >= m_width || y >= m_height || !(alpha > 0.0)) return;
  alpha = std::min(alpha, 1.0);
  const size_t k = 3 * (static_cast<size_t>(y) * m_width + x);
  const auto mix = [alpha](std::uint8_t under, std::uint8_t over) {
    return static_cast<std::uint8_t>(std::lround((1.0 - alpha) * under + alpha * over));
  };
  m_pixels[k] = mix(m_pixels[k], c.r);
  m_pixels[k + 1] = mix(m_pixels[k + 1], c.g);
  m_pixels[k + 2] = mix(m_pixels[k + 2], c.b);
}

void Image::fill(Rgb c) { fill_rect(0, 0, m_width, m_height, c); }

void Image::fill_rect(int x0, int y0, int x1, int y1, Rgb c) {
  x0 = std::max(x0, 0);
  y0 = std::max(y0, 0);
  x1 = std::min(x1, m_width);
  y1 = std::min(y1, m_height);
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) set_pixel(x, y, c);
}

void Image::draw_line(double x0, double y0, double x1, double y1, double thickness, Rgb c) {
  if (!std::isfinite(x0) || !std::isfinite(y0) || !std::isfinite(x1) || !std::isfinite(y1) || !(thickness > 0.0)) return;
  const double hw = 0.5 * thickness;
  const double dx = x1 - x0, dy = y1 - y0;
  const double len2 = dx * dx + dy * dy;
  const int px0 = std::max(0, static_cast<int>(std::floor(std::min(x0, x1) - hw - 1.0)));
  const int px1 = std::min(m_width - 1, static_cast<int>(std::ceil(std::max(x0, x1) + hw + 1.0)));
  const int py0 = std::max(0, static_cast<int>(std::floor(std::min(y0, y1) - hw - 1.0)));
  const int py1 = std::min(m_height - 1, static_cast<int>(std::ceil(std::max(y0, y1) + hw + 1.0)));
  for (int py = py0; py <= py1; ++py) {
    for (int px = px0; px <= px1; ++px) {
      const double qx = px + 0.5 - x0, qy = py + 0.5 - y0;
      const double t = len2 > 0.0 ? std::clamp((qx * dx + qy * dy) / len2, 0.0, 1.0) : 0.0;
      const double d = std::hypot(qx - t * dx, qy - t * dy);
      blend_pixel(px, py, c, clamp01(hw + 0.5 - d));
    }
  }
}

void Image::fill_circle(double cx, double cy, double radius, Rgb c) {
  if (!std::isfinite(cx) || !std::isfinite(cy) || !(radius > 0.0)) return;
  const int px0 = std::max(0, static_cast<int>(std::floor(cx - radius - 1.0)));
  const int px1 = std::min(m_width - 1, static_cast<int>(std::ceil(cx + radius + 1.0)));
  const int py0 = std::max(0, static_cast<int>(std::floor(cy - radius - 1.0)));
  const int py1 = std::min(m_height - 1, static_cast<int>(std::ceil(cy + radius + 1.0)));
  for (int py = py0; py <= py1; ++py)
    for (int px = px0; px <= px1; ++px)
      blend_pixel(px, py, c, clamp01(radius + 0.5 - std::hypot(px + 0.5 - cx, py + 0.5 - cy)));
}

int Image::text_width(const std::string& text, int scale) {
  return text.empty() ? 0 : (4 * static_cast<int>(text.size()) - 1) * scale;
}

int Image::draw_text(int x, int y, const std::string& text, int scale, Rgb c) {
  for (size_t i = 0; i < text.size(); ++i) {
    const std::string_view g = glyph(text[i]);
    const int gx = x + 4 * scale * static_cast<int>(i);
    for (int row = 0; row < 5; ++row)
      for (int col = 0; col < 3; ++col)
        if (g[3 * row + col] == '1')
          fill_rect(gx + col * scale, y + row * scale, gx + (col + 1) * scale, y + (row + 1) * scale, c);
  }
  return text_width(text, scale);
}

std::vector<std::uint8_t> Image::encode_png() const {
  if (m_pixels.empty()) throw_error("image: cannot encode an empty image");
  // libpng's simplified API: errors come back as a return value and a message, no setjmp.
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(m_width);
  image.height = static_cast<png_uint_32>(m_height);
  image.format = PNG_FORMAT_RGB;
  png_alloc_size_t size = 0;
  if (!png_image_write_to_memory(&image, nullptr, &size, 0, m_pixels.data(), 0, nullptr))
    throw_error("image: PNG encoding failed: {}", image.message);
  std::vector<std::uint8_t> out(size);
  if (!png_image_write_to_memory(&image, out.data(), &size, 0, m_pixels.data(), 0, nullptr))
    throw_error("image: PNG encoding failed: {}", image.message);
  out.resize(size);
  return out;
}

void Image::write_png(const std::filesystem::path& path) const {
  const std::vector<std::uint8_t> bytes = encode_png();
  write_file_atomic(
      path, [&](std::ostream& o) { o.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size())); },
      /*binary=*/true);
}

Image Image::read_png(const std::filesystem::path& path) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, path.c_str()))
    throw_input_error("{}: cannot read PNG: {}", path.string(), image.message);
  image.format = PNG_FORMAT_RGB;
  if (image.width == 0 || image.height == 0 || static_cast<unsigned long long>(image.width) * image.height > (1ULL << 28)) {
    png_image_free(&image);
    throw_input_error("{}: PNG size {} x {} not supported", path.string(), image.width, image.height);
  }
  Image out(static_cast<int>(image.width), static_cast<int>(image.height));
  png_color white{255, 255, 255};
  if (!png_image_finish_read(&image, &white, out.m_pixels.data(), 0, nullptr))
    throw_input_error("{}: cannot read PNG: {}", path.string(), image.message);
  return out;
}

}  // namespace mgcloth::cli
