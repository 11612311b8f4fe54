#include "chronomap/render/draw.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace chronomap {

namespace {

// 5x7 glyphs: seven rows, the five low bits of each row from left (bit 4) to right (bit 0).
struct Glyph {
  char c;
  uint8_t rows[7];
};

constexpr Glyph kFont[] = {
    {'0', {14, 17, 19, 21, 25, 17, 14}}, {'1', {4, 12, 4, 4, 4, 4, 14}},    {'2', {14, 17, 1, 2, 4, 8, 31}},
    {'3', {31, 2, 4, 2, 1, 17, 14}},     {'4', {2, 6, 10, 18, 31, 2, 2}},   {'5', {31, 16, 30, 1, 1, 17, 14}},
    {'6', {6, 8, 16, 30, 17, 17, 14}},   {'7', {31, 1, 2, 4, 8, 8, 8}},     {'8', {14, 17, 17, 14, 17, 17, 14}},
    {'9', {14, 17, 17, 15, 1, 2, 12}},   {'A', {14, 17, 17, 31, 17, 17, 17}}, {'B', {30, 17, 17, 30, 17, 17, 30}},
    {'C', {14, 17, 16, 16, 16, 17, 14}}, {'D', {28, 18, 17, 17, 17, 18, 28}}, {'E', {31, 16, 16, 30, 16, 16, 31}},
    {'F', {31, 16, 16, 30, 16, 16, 16}}, {'G', {14, 17, 16, 23, 17, 17, 15}}, {'H', {17, 17, 17, 31, 17, 17, 17}},
    {'I', {14, 4, 4, 4, 4, 4, 14}},      {'J', {7, 2, 2, 2, 2, 18, 12}},    {'K', {17, 18, 20, 24, 20, 18, 17}},
    {'L', {16, 16, 16, 16, 16, 16, 31}}, {'M', {17, 27, 21, 21, 17, 17, 17}}, {'N', {17, 17, 25, 21, 19, 17, 17}},
    {'O', {14, 17, 17, 17, 17, 17, 14}}, {'P', {30, 17, 17, 30, 16, 16, 16}}, {'Q', {14, 17, 17, 17, 21, 18, 13}},
    {'R', {30, 17, 17, 30, 20, 18, 17}}, {'S', {15, 16, 16, 14, 1, 1, 30}}, {'T', {31, 4, 4, 4, 4, 4, 4}},
    {'U', {17, 17, 17, 17, 17, 17, 14}}, {'V', {17, 17, 17, 17, 17, 10, 4}}, {'W', {17, 17, 17, 21, 21, 21, 10}},
    {'X', {17, 17, 10, 4, 10, 17, 17}},  {'Y', {17, 17, 17, 10, 4, 4, 4}},  {'Z', {31, 1, 2, 4, 8, 16, 31}},
    {' ', {0, 0, 0, 0, 0, 0, 0}},        {'.', {0, 0, 0, 0, 0, 12, 12}},    {',', {0, 0, 0, 0, 12, 4, 8}},
    {'-', {0, 0, 0, 31, 0, 0, 0}},       {'+', {0, 4, 4, 31, 4, 4, 0}},     {':', {0, 12, 12, 0, 12, 12, 0}},
    {'(', {2, 4, 8, 8, 8, 4, 2}},        {')', {8, 4, 2, 2, 2, 4, 8}},      {'/', {0, 1, 2, 4, 8, 16, 0}},
    {'%', {24, 25, 2, 4, 8, 19, 3}},     {'=', {0, 0, 31, 0, 31, 0, 0}},    {'_', {0, 0, 0, 0, 0, 0, 31}},
    {'x', {0, 17, 10, 4, 10, 17, 0}},    {'#', {10, 10, 31, 10, 31, 10, 10}}, {'\'', {4, 4, 8, 0, 0, 0, 0}},
    {'>', {8, 4, 2, 1, 2, 4, 8}},        {'<', {2, 4, 8, 16, 8, 4, 2}},     {'^', {4, 10, 17, 0, 0, 0, 0}},
};
// The unit metre's lower-case m.
constexpr uint8_t kMetre[7] = {0, 0, 26, 21, 21, 21, 21};
constexpr uint8_t kBox[7] = {31, 17, 17, 17, 17, 17, 31};
constexpr int kAdvance = 6;  // glyph width 5 plus one column of space

bool isLetter(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); }

const uint8_t* glyphOf(const std::string& text, size_t i) {
  char c = text[i];
  // A lone 'm' is the unit metre: "M" would read as mega.
  if (c == 'm' && (i == 0 || !isLetter(text[i - 1])) && (i + 1 == text.size() || !isLetter(text[i + 1]))) {
    return kMetre;
  }
  // 'x' has its own glyph (a multiplication sign); other lower case letters are capitals.
  if (c != 'x' && c >= 'a' && c <= 'z') c = static_cast<char>(c - 'a' + 'A');
  for (const Glyph& g : kFont) {
    if (g.c == c) return g.rows;
  }
  return kBox;
}

void setPixel(ImageRgb& image, int x, int y, Rgb colour) {
  if (x < 0 || y < 0 || x >= static_cast<int>(image.width) || y >= static_cast<int>(image.height)) return;
  image.pixels[static_cast<size_t>(y) * image.width + static_cast<size_t>(x)] = colour;
}

}  // namespace

int textWidth(const std::string& text, int scale) {
  return text.empty() ? 0 : (static_cast<int>(text.size()) * kAdvance - 1) * scale;
}

void drawText(ImageRgb& image, int x, int y, const std::string& text, Rgb colour, int scale) {
  for (size_t i = 0; i < text.size(); ++i) {
    const uint8_t* rows = glyphOf(text, i);
    const int gx = x + static_cast<int>(i) * kAdvance * scale;
    for (int r = 0; r < 7; ++r) {
      for (int c = 0; c < 5; ++c) {
        if (((rows[r] >> (4 - c)) & 1) == 0) continue;
        fillRect(image, gx + c * scale, y + r * scale, gx + (c + 1) * scale, y + (r + 1) * scale, colour);
      }
    }
  }
}

void fillRect(ImageRgb& image, int x0, int y0, int x1, int y1, Rgb colour) {
  x0 = std::max(x0, 0);
  y0 = std::max(y0, 0);
  x1 = std::min(x1, static_cast<int>(image.width));
  y1 = std::min(y1, static_cast<int>(image.height));
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) image.pixels[static_cast<size_t>(y) * image.width + static_cast<size_t>(x)] = colour;
  }
}

void drawLine(ImageRgb& image, int x0, int y0, int x1, int y1, Rgb colour, int thickness) {
  const int dx = std::abs(x1 - x0), dy = -std::abs(y1 - y0);
  const int sx = x0 < x1 ? 1 : -1, sy = y0 < y1 ? 1 : -1;
  int err = dx + dy;
  const int h = thickness / 2;
  while (true) {
    for (int oy = -h; oy < thickness - h; ++oy) {
      for (int ox = -h; ox < thickness - h; ++ox) setPixel(image, x0 + ox, y0 + oy, colour);
    }
    if (x0 == x1 && y0 == y1) break;
    const int e2 = 2 * err;
    if (e2 >= dy) {
      err += dy;
      x0 += sx;
    }
    if (e2 <= dx) {
      err += dx;
      y0 += sy;
    }
  }
}

void drawArrow(ImageRgb& image, int x0, int y0, int x1, int y1, Rgb colour, int thickness, int head_px) {
  const double dx = x1 - x0, dy = y1 - y0;
  const double length = std::hypot(dx, dy);
  if (length < 1.0) {
    drawLine(image, x0, y0, x1, y1, colour, thickness);
    return;
  }
  const double head = std::min(static_cast<double>(head_px), length / 2);
  const double ux = dx / length, uy = dy / length;
  // The shaft stops where the head begins, so that a thick shaft does not blunt the tip.
  const double bx = x1 - ux * head, by = y1 - uy * head;
  drawLine(image, x0, y0, static_cast<int>(std::lround(bx)), static_cast<int>(std::lround(by)), colour, thickness);
  // The head: a triangle of half-width head/2, filled by lines from the tip to its base.
  const double half = head / 2;
  const int steps = static_cast<int>(std::ceil(2 * half)) * 2;
  for (int k = 0; k <= steps; ++k) {
    const double t = -half + 2 * half * k / steps;
    const int px = static_cast<int>(std::lround(bx - uy * t)), py = static_cast<int>(std::lround(by + ux * t));
    drawLine(image, px, py, x1, y1, colour, 1);
  }
}

}  // namespace chronomap
