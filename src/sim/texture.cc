#include "superdyna/sim/texture.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>
#include <utility>

#include "superdyna/core/error.h"
#include "superdyna/sim/hash.h"

namespace superdyna::sim {

namespace {

constexpr int kMaxTextureSize = 16384;

// ------------------------------------------------------------------------------------------------
// Random numbers

/// Uniform numbers from a 64-bit Mersenne Twister, converted by hand (not through the standard
/// distributions, whose output differs between standard libraries) so a seed gives the same
/// texture everywhere. For the same reason no two draws are arguments of one call: C++ leaves their
/// order to the compiler (gcc evaluates arguments right to left, clang left to right), so each draw
/// is a statement of its own, in the order gcc drew them when the measured sequences were made.
class Random {
 public:
  explicit Random(std::uint64_t seed) : engine_(seed) {}

  std::uint64_t bits() { return engine_(); }
  /// Uniform in [0, 1).
  double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  /// Uniform integer in [lo, hi] (both inclusive).
  int uniformInt(int lo, int hi) {
    return lo + static_cast<int>(uniform() * static_cast<double>(hi - lo + 1));
  }
  bool chance(double probability) { return uniform() < probability; }
  /// A gray level in [lo, hi], both clamped to [0, 255].
  int gray(int lo, int hi) { return uniformInt(std::clamp(lo, 0, 255), std::clamp(hi, 0, 255)); }
  /// A gray level that differs from `gray` by at least min_step (up or down, whichever fits).
  int contrasting(int gray_level, int min_step, int max_step) {
    const int step = uniformInt(min_step, max_step);
    const bool up = gray_level + step <= 255 && (gray_level - step < 0 || chance(0.5));
    return std::clamp(up ? gray_level + step : gray_level - step, 0, 255);
  }

 private:
  std::mt19937_64 engine_;
};

// ------------------------------------------------------------------------------------------------
// Drawing in texels with sizes given in metres

/// Draws flat-gray shapes on the structure layer of a texture. Sizes are given in metres and
/// converted with the texel size, so a brick is a brick whatever the resolution.
class Painter {
 public:
  /// Draws on `canvas` (a header sharing its pixels).
  Painter(cv::Mat canvas, double texel_m, Random& random)
      : canvas_(std::move(canvas)), texel_m_(texel_m), random_(random) {}

  /// A painter whose drawing is confined to `box` (coordinates relative to the box's corner),
  /// for things seen through a window or printed on a panel.
  Painter region(const cv::Rect& box) {
    const cv::Rect inside = box & cv::Rect(0, 0, cols(), rows());
    return Painter(inside.empty() ? cv::Mat() : canvas_(inside), texel_m_, random_);
  }
  bool empty() const { return canvas_.empty(); }

  Random& random() { return random_; }
  cv::Mat& canvas() { return canvas_; }
  int cols() const { return canvas_.cols; }
  int rows() const { return canvas_.rows; }
  double texelM() const { return texel_m_; }

  /// Texels in a length [m], at least 1.
  int texels(double metres) const {
    return std::max(1, static_cast<int>(std::lround(metres / texel_m_)));
  }
  /// Texels in a random length in [lo_m, hi_m].
  int texels(double lo_m, double hi_m) { return texels(random_.uniform(lo_m, hi_m)); }
  /// Whether a feature of this size [m] spans enough texels (3) to be drawn recognisably.
  bool resolves(double metres) const { return metres / texel_m_ >= 3.0; }
  /// How many items a density [1/m^2] gives on the whole texture (randomly rounded), at most one
  /// per 4 texels: on coarse textures small items cannot be denser than the texels.
  int countFor(double per_m2) {
    const double texels = static_cast<double>(cols()) * rows();
    const double expected = std::min(per_m2 * texels * texel_m_ * texel_m_, 0.25 * texels);
    return static_cast<int>(expected) + (random_.chance(expected - std::floor(expected)) ? 1 : 0);
  }
  cv::Point randomPoint() {
    return {random_.uniformInt(0, cols() - 1), random_.uniformInt(0, rows() - 1)};
  }

  void fill(const cv::Rect& box, int gray) { cv::rectangle(canvas_, box, cv::Scalar(gray), -1); }
  void outline(const cv::Rect& box, int thickness, int gray) {
    for (int i = 0; i < thickness; ++i) {
      const cv::Rect inner(box.x + i, box.y + i, box.width - 2 * i, box.height - 2 * i);
      if (inner.width <= 0 || inner.height <= 0) return;
      cv::rectangle(canvas_, inner, cv::Scalar(gray), 1);
    }
  }
  void line(cv::Point a, cv::Point b, int thickness, int gray) {
    cv::line(canvas_, a, b, cv::Scalar(gray), std::max(1, thickness), cv::LINE_8);
  }
  void disk(cv::Point centre, int radius, int gray) {
    cv::circle(canvas_, centre, std::max(1, radius), cv::Scalar(gray), -1, cv::LINE_8);
  }
  void ellipse(cv::Point centre, cv::Size axes, double angle_deg, int gray) {
    cv::ellipse(canvas_, centre, axes, angle_deg, 0.0, 360.0, cv::Scalar(gray), -1, cv::LINE_8);
  }
  void rotatedRect(cv::Point2f centre, cv::Size2f size, float angle_deg, int gray) {
    cv::Point2f corners_f[4];
    cv::RotatedRect(centre, size, angle_deg).points(corners_f);
    cv::Point corners[4];
    for (int i = 0; i < 4; ++i)
      corners[i] = corners_f[i];
    cv::fillConvexPoly(canvas_, corners, 4, cv::Scalar(gray), cv::LINE_8);
  }

  /// An irregular star-shaped polygon (stain, splash, leaf, print motif) of about `radius`.
  void blob(cv::Point centre, double radius, int gray) {
    const int vertices = random_.uniformInt(5, 11);
    std::vector<cv::Point> polygon;
    polygon.reserve(static_cast<std::size_t>(vertices));
    const double phase = random_.uniform(0.0, 2.0 * M_PI);
    for (int i = 0; i < vertices; ++i) {
      const double angle = phase + 2.0 * M_PI * (i + random_.uniform(-0.3, 0.3)) / vertices;
      const double r = radius * random_.uniform(0.45, 1.0);
      polygon.emplace_back(centre.x + static_cast<int>(r * std::cos(angle)),
                           centre.y + static_cast<int>(r * std::sin(angle)));
    }
    cv::fillPoly(canvas_, std::vector<std::vector<cv::Point>>{polygon}, cv::Scalar(gray));
  }

  /// A crack: a jagged random walk of `length` texels with occasional branches.
  void crack(cv::Point start, double length, int gray) {
    double heading = random_.uniform(0.0, 2.0 * M_PI);
    cv::Point2d p(start);
    const double step = std::max(2.0, length / 12.0);
    for (double done = 0.0; done < length; done += step) {
      heading += random_.uniform(-0.7, 0.7);
      const cv::Point2d next = p + step * cv::Point2d(std::cos(heading), std::sin(heading));
      line(p, next, 1, gray);
      if (random_.chance(0.1)) crack(next, length * 0.3, gray);
      p = next;
    }
  }

  /// Lines of "writing" filling `box`: glyphs made of a few bars, rings and dots in cells of the
  /// given height, with word gaps; dense corners like real signs, labels and book spines.
  void text(const cv::Rect& box, int glyph_height, int gray) {
    glyph_height = std::max(3, glyph_height);
    const int stroke = std::max(1, glyph_height / 6);
    const int advance = std::max(2, glyph_height * 2 / 3);
    for (int y = box.y; y + glyph_height <= box.y + box.height; y += glyph_height * 3 / 2) {
      for (int x = box.x; x + advance <= box.x + box.width; x += advance) {
        if (random_.chance(0.15)) continue;  // word gap
        glyph(cv::Rect(x, y, advance - stroke, glyph_height), stroke, gray);
      }
    }
  }

  /// Many small marks [min_m, max_m] of random gray levels in [gray_lo, gray_hi].
  void speckles(int count, double min_m, double max_m, int gray_lo, int gray_hi) {
    const double min_tx = std::max(1.0, min_m / texel_m_);
    const double max_tx = std::max(min_tx, max_m / texel_m_);
    for (int i = 0; i < count; ++i) {
      const cv::Point p = randomPoint();
      const int size = static_cast<int>(std::lround(random_.uniform(min_tx, max_tx)));
      const int gray = random_.gray(gray_lo, gray_hi);
      if (size <= 2 || random_.chance(0.5)) {
        fill(cv::Rect(p.x, p.y, size, std::max(1, size + random_.uniformInt(-1, 1))), gray);
      } else {
        blob(p, 0.5 * size + 0.5, gray);
      }
    }
  }

  /// Parallel bars of one gray level across `box` (stripes, blinds, zebra crossings, grilles).
  void stripes(const cv::Rect& box, int period, int width, bool vertical, int gray) {
    period = std::max(2, period);
    const int extent = vertical ? box.width : box.height;
    for (int offset = 0; offset < extent; offset += period) {
      fill(vertical ? cv::Rect(box.x + offset, box.y, width, box.height)
                    : cv::Rect(box.x, box.y + offset, box.width, width),
           gray);
    }
  }

  /// A checkerboard (plaid when the two gray levels differ little) of `cell` texels over `box`.
  void checks(const cv::Rect& box, int cell, int gray) {
    cell = std::max(2, cell);
    for (int y = 0; y < box.height; y += cell) {
      for (int x = ((y / cell) % 2) * cell; x < box.width; x += 2 * cell) {
        fill(cv::Rect(box.x + x, box.y + y, std::min(cell, box.width - x),
                      std::min(cell, box.height - y)),
             gray);
      }
    }
  }

 private:
  void glyph(const cv::Rect& cell, int stroke, int gray) {
    const int parts = random_.uniformInt(1, 3);
    for (int i = 0; i < parts; ++i) {
      switch (random_.uniformInt(0, 4)) {
        case 0:  // vertical bar
          fill(cv::Rect(cell.x + random_.uniformInt(0, std::max(0, cell.width - stroke)), cell.y,
                        stroke, cell.height),
               gray);
          break;
        case 1:  // horizontal bar at top, middle or bottom
          fill(cv::Rect(cell.x, cell.y + random_.uniformInt(0, 2) * (cell.height - stroke) / 2,
                        cell.width, stroke),
               gray);
          break;
        case 2:  // bowl
          cv::ellipse(canvas_, cv::Point(cell.x + cell.width / 2, cell.y + cell.height * 2 / 3),
                      cv::Size(std::max(1, cell.width / 2), std::max(1, cell.height / 3)), 0.0, 0.0,
                      360.0, cv::Scalar(gray), stroke, cv::LINE_8);
          break;
        case 3:  // diagonal
          line(cell.tl(), cell.br(), stroke, gray);
          break;
        default:  // dot
          fill(cv::Rect(cell.x + cell.width / 2, cell.y, stroke + 1, stroke + 1), gray);
          break;
      }
    }
  }

  cv::Mat canvas_;
  double texel_m_;
  Random& random_;
};

// ------------------------------------------------------------------------------------------------
// Styles: each paints the flat-gray structure layer and says how to finish it.

/// How the noise and the contrast of a style are finished after its structures are drawn.
struct StyleLook {
  double noise_gray = 12.0;    ///< Std of the fractal noise added [gray levels].
  double stain_gray = 12.0;    ///< Step of the thresholded-noise stains [gray levels].
  double target_mean = 120.0;  ///< Mean gray level of the final texture.
  double target_std = 55.0;    ///< Std of the final texture [gray levels].
};

void paintRoadMarkings(Painter& p, int paint_gray) {
  Random& r = p.random();
  const int line_width = p.texels(0.10, 0.15);
  // Dashed lane lines along u.
  int lanes = 0;
  if (p.resolves(0.1)) {
    lanes = p.countFor(0.004);
    lanes += r.uniformInt(0, 2);
  }
  for (int i = 0; i < lanes; ++i) {
    const int y = r.uniformInt(0, p.rows() - 1);
    const int dash = p.texels(2.0, 4.0), gap = p.texels(2.0, 6.0);
    const bool solid = r.chance(0.3);
    for (int x = r.uniformInt(-dash, 0); x < p.cols(); x += dash + gap) {
      p.fill(cv::Rect(x, y, solid ? dash + gap : dash, line_width), paint_gray);
    }
  }
  // Rows of parking stalls: lines across v every 2.5 m.
  const int stall_rows = p.countFor(0.003);
  for (int i = 0; i < stall_rows; ++i) {
    const int y = r.uniformInt(0, p.rows() - 1), length = p.texels(4.5, 5.5);
    const int spacing = p.texels(2.3, 2.8);
    for (int x = r.uniformInt(0, spacing); x < p.cols(); x += spacing) {
      p.fill(cv::Rect(x, y, line_width, length), paint_gray);
    }
    p.fill(cv::Rect(0, y, p.cols(), line_width), paint_gray);
  }
  // Zebra crossings, painted arrows and words.
  const int crossings = p.countFor(0.002);
  for (int i = 0; i < crossings; ++i) {
    const cv::Point c = p.randomPoint();
    const int height = p.texels(3.0, 4.0);
    const int width = p.texels(6.0, 10.0);
    p.stripes(cv::Rect(c.x, c.y, width, height), p.texels(1.0), p.texels(0.5), true, paint_gray);
  }
  const int words = p.countFor(0.01);
  for (int i = 0; i < words; ++i) {
    const cv::Point c = p.randomPoint();
    const int height = p.texels(0.4, 1.2);
    p.text(cv::Rect(c.x, c.y, height * r.uniformInt(2, 6), height), height, paint_gray);
  }
}

void paintManhole(Painter& p, cv::Point centre, int base) {
  Random& r = p.random();
  const int radius = p.texels(0.25, 0.4);
  p.disk(centre, radius, r.contrasting(base, 20, 50));
  cv::circle(p.canvas(), centre, radius, cv::Scalar(r.gray(10, 50)), std::max(1, radius / 8));
  const int bar = std::max(1, radius / 6);
  const cv::Rect grille(centre.x - radius / 2, centre.y - radius / 2, radius, radius);
  const int grille_gray = r.gray(10, 50);
  const bool vertical = r.chance(0.5);
  p.stripes(grille, 2 * bar, bar, vertical, grille_gray);
}

StyleLook paintGround(Painter& p) {
  Random& r = p.random();
  const int base = r.gray(70, 120);
  p.canvas().setTo(base);
  // Repairs and fresher or older asphalt, mostly aligned with the road.
  for (int i = p.countFor(0.03); i > 0; --i) {
    const float angle = r.chance(0.6) ? 90.0f * r.uniformInt(0, 1) : r.uniform(0.0, 180.0);
    const int gray = r.contrasting(base, 12, 35);
    const int height = p.texels(0.4, 3.0);
    const int width = p.texels(0.5, 4.0);
    p.rotatedRect(p.randomPoint(), cv::Size2f(width, height), angle, gray);
  }
  for (int i = p.countFor(0.03); i > 0; --i) {  // oil stains, wet patches
    const int gray = r.contrasting(base, 15, 40);
    const int radius = p.texels(0.1, 0.8);
    p.blob(p.randomPoint(), radius, gray);
  }
  for (int i = p.countFor(0.004); i > 0; --i)
    paintManhole(p, p.randomPoint(), base);
  for (int i = p.countFor(0.15); i > 0; --i) {
    const int gray = r.gray(base - 60, base - 30);
    const int length = p.texels(0.3, 2.0);
    p.crack(p.randomPoint(), length, gray);
  }
  paintRoadMarkings(p, r.gray(200, 245));
  // Aggregate, chips, gravel and leaves.
  p.speckles(p.countFor(300.0), 0.01, 0.03, base - 70, base + 90);
  p.speckles(p.countFor(15.0), 0.03, 0.10, 0, 255);
  return {.noise_gray = 16.0,
          .stain_gray = 14.0,
          .target_mean = r.uniform(95, 130),
          .target_std = 50.0};
}

/// The wall between the windows: bricks, stone blocks, concrete panels or plaster.
void paintWallMaterial(Painter& p, int base) {
  Random& r = p.random();
  const int kind = r.uniformInt(0, 3);
  if (kind == 0 && p.resolves(0.065)) {  // bricks in running bond
    const int brick_h = p.texels(0.065), brick_w = p.texels(0.215), mortar = p.texels(0.01);
    p.canvas().setTo(r.contrasting(base, 25, 60));  // mortar
    for (int row = 0, y = 0; y < p.rows(); ++row, y += brick_h + mortar) {
      const int shift = (row % 2) * (brick_w + mortar) / 2;
      for (int x = -shift; x < p.cols(); x += brick_w + mortar) {
        p.fill(cv::Rect(x, y, brick_w, brick_h), r.gray(base - 25, base + 25));
      }
    }
  } else if (kind == 1 && p.resolves(0.2)) {  // stone blocks of varying length
    const int block_h = p.texels(0.25, 0.45), joint = p.texels(0.015);
    p.canvas().setTo(r.contrasting(base, 25, 50));
    for (int y = 0; y < p.rows(); y += block_h + joint) {
      for (int x = -r.uniformInt(0, block_h); x < p.cols();) {
        const int width = p.texels(0.4, 1.0);
        p.fill(cv::Rect(x, y, width, block_h), r.gray(base - 20, base + 20));
        x += width + joint;
      }
    }
  } else if (kind == 2) {  // concrete panels with tie holes
    p.canvas().setTo(base);
    const int panel_w = p.texels(1.2, 2.5), panel_h = p.texels(0.6, 1.5);
    for (int y = 0; y < p.rows(); y += panel_h) {
      for (int x = 0; x < p.cols(); x += panel_w) {
        p.fill(cv::Rect(x, y, panel_w, panel_h), r.gray(base - 15, base + 15));
        p.outline(cv::Rect(x, y, panel_w, panel_h), p.texels(0.01), r.gray(base - 60, base - 30));
        for (int k = 0; k < 4; ++k) {
          p.disk(
              cv::Point(x + panel_w * (1 + 2 * (k % 2)) / 4, y + panel_h * (1 + 2 * (k / 2)) / 4),
              p.texels(0.015), r.gray(10, 60));
        }
      }
    }
  } else {  // plaster with patches
    p.canvas().setTo(base);
    for (int i = p.countFor(0.2); i > 0; --i) {
      const int gray = r.contrasting(base, 10, 30);
      const int radius = p.texels(0.1, 0.6);
      p.blob(p.randomPoint(), radius, gray);
    }
  }
}

void paintWindow(Painter& p, const cv::Rect& box, int frame_gray, int glass_gray, int mullions) {
  Random& r = p.random();
  const int frame = p.texels(0.05, 0.09);
  p.fill(box, glass_gray);
  // Reflections of the street: a few slanted bands, seen only in the glass.
  Painter glass = p.region(box);
  for (int i = r.uniformInt(0, 2); i > 0 && !glass.empty(); --i) {
    const int cy = r.uniformInt(0, box.height);
    const int cx = r.uniformInt(0, box.width);
    const int gray = r.contrasting(glass_gray, 15, 50);
    const double angle = r.uniform(15, 40);
    glass.rotatedRect(cv::Point2f(cx, cy), cv::Size2f(box.width * 0.15f, box.height * 1.2f), angle,
                      gray);
  }
  const int curtain_gray = r.chance(0.3) ? r.gray(150, 240) : glass_gray;  // curtain or blind
  p.fill(cv::Rect(box.x, box.y, box.width, box.height * r.uniformInt(0, 2) / 5), curtain_gray);
  if (r.chance(0.25)) {
    p.stripes(cv::Rect(box.x, box.y, box.width, box.height / 2), p.texels(0.04), 1, false,
              r.gray(100, 200));
  }
  p.outline(box, frame, frame_gray);
  for (int i = 1; i <= mullions; ++i) {
    p.fill(cv::Rect(box.x + box.width * i / (mullions + 1) - frame / 2, box.y, frame, box.height),
           frame_gray);
  }
  p.fill(cv::Rect(box.x + frame, box.y + box.height / 3, box.width - 2 * frame, frame / 2 + 1),
         frame_gray);  // transom
  const int sill = p.texels(0.06);
  p.fill(cv::Rect(box.x - sill, box.y + box.height, box.width + 2 * sill, sill), r.gray(170, 240));
}

void paintShopFront(Painter& p, int top, int bottom, int base) {
  Random& r = p.random();
  for (int x = r.uniformInt(-p.texels(2.0), 0); x < p.cols();) {
    const int width = p.texels(2.0, 6.0);
    const int sign_h = p.texels(0.4, 0.7);
    const cv::Rect sign(x + width / 10, top + p.texels(0.2), width * 8 / 10, sign_h);
    const int sign_gray = r.gray(0, 255);
    p.fill(sign, sign_gray);
    p.text(cv::Rect(sign.x + sign_h / 4, sign.y + sign_h / 4, sign.width - sign_h / 2, sign_h),
           sign_h / 2, r.contrasting(sign_gray, 70, 160));
    const cv::Rect shop(x + width / 10, sign.y + sign_h + p.texels(0.2), width * 8 / 10,
                        bottom - sign.y - sign_h - p.texels(0.2));
    const int mullions = r.uniformInt(1, 3);
    const int glass_gray = r.gray(20, 80);
    paintWindow(p, shop, r.gray(20, 90), glass_gray, mullions);
    const int door_w = p.texels(0.9, 1.2);
    const cv::Rect door(shop.x + r.uniformInt(0, std::max(0, shop.width - door_w)),
                        bottom - p.texels(2.2), door_w, p.texels(2.2));
    p.fill(door, r.gray(10, 120));
    p.outline(door, p.texels(0.05), r.contrasting(base, 30, 80));
    // Posters and stickers in the shop window.
    for (int i = r.uniformInt(0, 4); i > 0; --i) {
      const int w = p.texels(0.2, 0.6), h = p.texels(0.3, 0.8);
      const int y = shop.y + r.uniformInt(0, std::max(0, shop.height - h));
      const cv::Rect poster(shop.x + r.uniformInt(0, std::max(0, shop.width - w)), y, w, h);
      const int gray = r.gray(120, 255);
      p.fill(poster, gray);
      p.text(poster, std::max(3, h / 8), r.contrasting(gray, 80, 150));
    }
    x += width;
  }
}

StyleLook paintFacade(Painter& p) {
  Random& r = p.random();
  const int base = r.gray(90, 200);
  paintWallMaterial(p, base);
  const int floor_h = p.texels(3.0, 3.6);
  const int window_w = p.texels(0.9, 1.6), window_h = p.texels(1.3, 1.9);
  const int spacing = window_w + p.texels(0.8, 2.2);
  const int frame_gray = r.chance(0.5) ? r.gray(180, 250) : r.gray(10, 70);
  const int glass_gray = r.gray(15, 90);
  const int mullions = r.uniformInt(0, 2);
  // Floors counted upwards from the bottom rows; the ground floor holds shops.
  const bool shops = r.chance(0.7);
  for (int k = 0, bottom = p.rows(); bottom > 0; ++k, bottom -= floor_h) {
    const int top = bottom - floor_h;
    const int cornice_gray = r.contrasting(base, 20, 50);
    p.fill(cv::Rect(0, top, p.cols(), p.texels(0.12, 0.25)), cornice_gray);
    if (k == 0 && shops) {
      paintShopFront(p, top, bottom, base);
      continue;
    }
    const int sill_y = bottom - p.texels(0.9) - window_h;
    for (int x = r.uniformInt(0, spacing / 2); x < p.cols(); x += spacing) {
      paintWindow(p, cv::Rect(x, sill_y, window_w, window_h), frame_gray,
                  r.chance(0.2) ? r.gray(10, 150) : glass_gray, mullions);
      if (r.chance(0.08)) {  // air conditioner under the window
        const cv::Rect unit(x + window_w / 4, sill_y + window_h + p.texels(0.15), p.texels(0.8),
                            p.texels(0.5));
        p.fill(unit, r.gray(160, 230));
        p.stripes(unit, p.texels(0.04), 1, false, r.gray(60, 120));
      }
    }
  }
  for (int i = p.countFor(0.02); i > 0; --i) {  // drain pipes
    const int gray = r.contrasting(base, 30, 80);
    const int width = p.texels(0.08, 0.12);
    p.fill(cv::Rect(r.uniformInt(0, p.cols()), 0, width, p.rows()), gray);
  }
  for (int i = p.countFor(0.05); i > 0; --i) {  // plaques, small signs, graffiti
    const cv::Point c = p.randomPoint();
    if (r.chance(0.5)) {
      const int height = p.texels(0.15, 0.4);
      const cv::Rect plaque(c.x, c.y, p.texels(0.2, 0.6), height);
      const int gray = r.gray(0, 255);
      p.fill(plaque, gray);
      p.text(plaque, std::max(3, plaque.height / 5), r.contrasting(gray, 80, 150));
    } else {
      const int gray = r.gray(0, 255);
      p.blob(c, p.texels(0.2, 0.8), gray);
    }
  }
  p.speckles(p.countFor(40.0), 0.01, 0.04, base - 80, base + 80);
  return {.noise_gray = 10.0,
          .stain_gray = 10.0,
          .target_mean = r.uniform(110, 145),
          .target_std = 55.0};
}

/// A poster or framed picture: a photo-like layout of shapes, with a caption.
void paintPoster(Painter& p, const cv::Rect& box) {
  Random& r = p.random();
  const int paper = r.gray(0, 255);
  p.fill(box, paper);
  Painter print = p.region(box);
  if (print.empty()) return;
  for (int i = r.uniformInt(3, 10); i > 0; --i) {
    const int cy = r.uniformInt(0, box.height);
    const cv::Point c(r.uniformInt(0, box.width), cy);
    const int size = std::max(2, std::min(box.width, box.height) / r.uniformInt(3, 8));
    if (r.chance(0.5)) {
      print.blob(c, size, r.gray(0, 255));
    } else {
      const int gray = r.gray(0, 255);
      print.fill(cv::Rect(c.x - size / 2, c.y - size / 2, size, size * r.uniformInt(1, 3)), gray);
    }
  }
  const int caption_h = std::max(3, box.height / 12);
  print.text(
      cv::Rect(caption_h, box.height - 3 * caption_h, box.width - 2 * caption_h, 2 * caption_h),
      caption_h, r.contrasting(paper, 80, 160));
  const int frame_gray = r.gray(0, 255);
  p.outline(box, p.texels(0.02, 0.05), frame_gray);
}

void paintBookshelf(Painter& p, const cv::Rect& box) {
  Random& r = p.random();
  const int board = p.texels(0.02, 0.03), shelf_h = p.texels(0.3, 0.4);
  const int wood = r.gray(60, 200);
  p.fill(box, r.gray(10, 50));  // shadowed back
  for (int y = box.y; y + shelf_h <= box.y + box.height; y += shelf_h) {
    p.fill(cv::Rect(box.x, y + shelf_h - board, box.width, board), wood);
    for (int x = box.x; x < box.x + box.width;) {
      const int w = p.texels(0.02, 0.06);
      const int h = std::min(shelf_h - board - 1, p.texels(0.15, 0.3));
      const int spine = r.gray(20, 250);
      const cv::Rect book(x, y + shelf_h - board - h, w, h);
      p.fill(book, spine);
      if (w >= 6) p.text(cv::Rect(book.x + 1, book.y + h / 4, w - 2, h / 2), w / 2, r.gray(0, 255));
      x += w + (r.chance(0.1) ? p.texels(0.05, 0.2) : 0);
    }
  }
  p.outline(box, board, wood);
}

StyleLook paintIndoor(Painter& p) {
  Random& r = p.random();
  const int base = r.gray(140, 220);
  p.canvas().setTo(base);
  p.fill(cv::Rect(0, p.rows() - p.texels(0.1), p.cols(), p.texels(0.1)), r.gray(20, 100));
  for (int i = p.countFor(0.05); i > 0; --i) {  // doors at the floor
    const int w = p.texels(0.85, 1.0), h = std::min(p.rows(), p.texels(2.0, 2.1));
    const cv::Rect door(r.uniformInt(0, p.cols()), p.rows() - h, w, h);
    const int leaf = r.gray(40, 230);
    p.fill(door, leaf);
    p.outline(door, p.texels(0.06), r.contrasting(leaf, 30, 80));
    p.outline(cv::Rect(door.x + w / 6, door.y + h / 10, w * 2 / 3, h / 3), 2,
              r.contrasting(leaf, 20, 50));
    p.disk(cv::Point(door.x + w * 5 / 6, door.y + h / 2), p.texels(0.03), r.gray(0, 255));
  }
  for (int i = p.countFor(0.06); i > 0; --i) {
    const cv::Point c = p.randomPoint();
    const int height = p.texels(0.7, 2.0);
    paintBookshelf(p, cv::Rect(c.x, c.y, p.texels(0.8, 2.0), height));
  }
  for (int i = p.countFor(0.03); i > 0; --i) {  // whiteboards with scribbles
    const cv::Point c = p.randomPoint();
    const int height = p.texels(0.8, 1.2);
    const cv::Rect board(c.x, c.y, p.texels(1.2, 2.0), height);
    p.fill(board, r.gray(215, 250));
    for (int k = r.uniformInt(2, 5); k > 0; --k) {
      const int h = p.texels(0.04, 0.08);
      const int ink = r.gray(10, 90);
      const int y = board.y + r.uniformInt(0, board.height - 2 * h);
      p.text(cv::Rect(board.x + h, y, board.width - 2 * h, h), h, ink);
    }
    p.outline(board, p.texels(0.02), r.gray(100, 180));
  }
  for (int i = p.countFor(0.35); i > 0; --i) {  // posters and pictures
    const cv::Point c = p.randomPoint();
    const int height = p.texels(0.4, 1.2);
    paintPoster(p, cv::Rect(c.x, c.y, p.texels(0.3, 1.0), height));
  }
  for (int i = p.countFor(1.5); i > 0; --i) {  // notes, switches, sockets, labels
    const cv::Point c = p.randomPoint();
    const int height = p.texels(0.06, 0.2);
    const cv::Rect note(c.x, c.y, p.texels(0.06, 0.2), height);
    const int gray = r.contrasting(base, 40, 120);
    p.fill(note, gray);
    p.text(note, std::max(3, note.height / 4), r.contrasting(gray, 60, 150));
  }
  p.speckles(p.countFor(20.0), 0.01, 0.03, base - 90, base + 60);
  return {
      .noise_gray = 6.0, .stain_gray = 6.0, .target_mean = r.uniform(120, 150), .target_std = 55.0};
}

void paintWheel(Painter& p, cv::Point centre, int radius, int arch_gray) {
  Random& r = p.random();
  p.disk(centre, radius * 115 / 100, arch_gray);  // wheel arch
  p.disk(centre, radius, r.gray(10, 40));         // tyre
  const int rim_radius = radius * 6 / 10;
  p.disk(centre, rim_radius, r.gray(120, 220));
  const int spokes = r.uniformInt(4, 10);
  const double phase = r.uniform(0.0, M_PI);
  for (int i = 0; i < spokes; ++i) {
    const double a = phase + 2.0 * M_PI * i / spokes;
    p.line(centre,
           centre + cv::Point(static_cast<int>(rim_radius * std::cos(a)),
                              static_cast<int>(rim_radius * std::sin(a))),
           std::max(1, rim_radius / 8), r.gray(20, 80));
  }
  p.disk(centre, std::max(1, rim_radius / 4), r.gray(150, 240));
}

/// One car seen from the side in `box` (front to the right).
void paintCar(Painter& p, const cv::Rect& box) {
  Random& r = p.random();
  const int body = r.gray(25, 235);
  const int w = box.width, h = box.height;
  p.fill(box, body);
  // Glasshouse: dark glass with a body-coloured pillar and reflections.
  const cv::Rect glass(box.x + w * 22 / 100, box.y + h * 6 / 100, w * 58 / 100, h * 33 / 100);
  const int glass_gray = r.gray(10, 70);
  p.fill(glass, glass_gray);
  if (Painter inside = p.region(glass); !inside.empty()) {
    inside.rotatedRect(cv::Point2f(glass.width * 0.3f, glass.height * 0.5f),
                       cv::Size2f(glass.width * 0.08f, glass.height * 1.3f), 30.0f,
                       r.contrasting(glass_gray, 30, 70));
  }
  p.fill(cv::Rect(box.x + w * 50 / 100, glass.y, w * 3 / 100, glass.height), body);
  p.outline(glass, 1, r.gray(5, 40));
  // Door seams, sill, bumpers, handles, lights, mirror.
  const int seam = r.contrasting(body, 40, 90);
  for (const int sx : {w * 22 / 100, w * 50 / 100, w * 79 / 100}) {
    p.line(cv::Point(box.x + sx, glass.y + glass.height),
           cv::Point(box.x + sx, box.y + h * 85 / 100), 1, seam);
  }
  p.fill(cv::Rect(box.x, box.y + h * 86 / 100, w, h * 6 / 100), r.gray(15, 70));  // sill
  p.line(cv::Point(box.x, box.y + h * 55 / 100), cv::Point(box.x + w, box.y + h * 53 / 100), 1,
         seam);  // crease
  for (const int hx : {w * 40 / 100, w * 70 / 100}) {
    p.fill(cv::Rect(box.x + hx, box.y + h * 47 / 100, w * 5 / 100, h * 3 / 100), seam);
  }
  p.fill(cv::Rect(box.x + w * 95 / 100, box.y + h * 42 / 100, w * 5 / 100, h * 10 / 100),
         r.gray(200, 255));  // head light
  p.fill(cv::Rect(box.x, box.y + h * 42 / 100, w * 4 / 100, h * 12 / 100), r.gray(60, 140));
  p.fill(cv::Rect(box.x + w * 80 / 100, box.y + h * 36 / 100, w * 4 / 100, h * 6 / 100), seam);
  const cv::Rect plate(box.x + w * 2 / 100, box.y + h * 65 / 100, w * 12 / 100, h * 9 / 100);
  p.fill(plate, r.gray(210, 250));
  p.text(plate, std::max(3, plate.height * 2 / 3), r.gray(0, 50));
  const int wheel_r = std::max(2, h * 22 / 100);
  for (const int wx : {w * 17 / 100, w * 83 / 100}) {
    paintWheel(p, cv::Point(box.x + wx, box.y + h * 80 / 100), wheel_r, r.gray(10, 40));
  }
  for (int i = r.uniformInt(0, 3); i > 0; --i) {  // stickers, badges, dents
    const int cy = box.y + r.uniformInt(h / 2, h);
    const cv::Point c(box.x + r.uniformInt(0, w), cy);
    const int gray = r.contrasting(body, 40, 120);
    p.blob(c, std::max(2, h / r.uniformInt(12, 30)), gray);
  }
}

StyleLook paintVehicle(Painter& p) {
  Random& r = p.random();
  p.canvas().setTo(r.gray(20, 60));
  for (int y = 0; y < p.rows();) {
    const int h = p.texels(1.35, 1.6);
    for (int x = r.uniformInt(-p.texels(2.0), 0); x < p.cols();) {
      const int w = p.texels(3.8, 4.9);
      paintCar(p, cv::Rect(x, y, w, h));
      x += w + p.texels(0.0, 0.3);
    }
    y += h;
  }
  p.speckles(p.countFor(30.0), 0.01, 0.03, 0, 255);  // dust, mud, chipped paint
  return {
      .noise_gray = 5.0, .stain_gray = 6.0, .target_mean = r.uniform(100, 140), .target_std = 60.0};
}

/// A garment pattern over `box` with two gray levels.
void paintGarment(Painter& p, const cv::Rect& box) {
  Random& r = p.random();
  const int cloth = r.gray(15, 240), ink = r.contrasting(cloth, 40, 140);
  p.fill(box, cloth);
  switch (r.uniformInt(0, 5)) {
    case 0: {
      const bool vertical = r.chance(0.3);
      const int width = p.texels(0.01, 0.03);
      p.stripes(box, p.texels(0.02, 0.08), width, vertical, ink);
    } break;
    case 1:
      p.checks(box, p.texels(0.02, 0.06), ink);
      break;
    case 2:  // dots
      for (int i = box.area() / std::max(1, p.texels(0.05) * p.texels(0.05)); i > 0; --i) {
        const int radius = p.texels(0.005, 0.015);
        const int y = box.y + r.uniformInt(0, box.height);
        p.disk(cv::Point(box.x + r.uniformInt(0, box.width), y), radius, ink);
      }
      break;
    case 3: {  // print with a logo and lettering
      const cv::Rect logo(box.x + box.width / 4, box.y + box.height / 5, box.width / 2,
                          box.height / 4);
      p.fill(logo, ink);
      p.text(logo, std::max(3, logo.height / 3), cloth);
      break;
    }
    case 4:  // jacket: zip, pockets, seams
      p.line(cv::Point(box.x + box.width / 2, box.y), cv::Point(box.x + box.width / 2, box.br().y),
             std::max(1, p.texels(0.01)), ink);
      for (const int px : {box.x + box.width / 8, box.x + box.width * 5 / 8}) {
        p.outline(cv::Rect(px, box.y + box.height * 6 / 10, box.width / 4, box.height / 6), 1, ink);
      }
      break;
    default:  // plain cloth with creases
      for (int i = r.uniformInt(3, 8); i > 0; --i) {
        const int ay = box.y + r.uniformInt(0, box.height);
        const cv::Point a(box.x + r.uniformInt(0, box.width), ay);
        const int gray = r.contrasting(cloth, 20, 50);
        const int dy = r.uniformInt(5, 30);
        p.line(a, a + cv::Point(r.uniformInt(-20, 20), dy), 1, gray);
      }
      break;
  }
}

/// One person seen from the front or the back in `box`.
void paintPerson(Painter& p, const cv::Rect& box) {
  Random& r = p.random();
  const int w = box.width, h = box.height;
  const int skin = r.gray(70, 210), hair = r.gray(5, 90);
  p.fill(box, r.gray(30, 200));  // what the sides of the box show between limbs
  const cv::Rect head(box.x + w * 3 / 10, box.y, w * 4 / 10, h * 13 / 100);
  p.ellipse((head.tl() + head.br()) / 2, cv::Size(head.width / 2, head.height / 2), 0.0, skin);
  p.ellipse(cv::Point(head.x + head.width / 2, head.y + head.height / 4),
            cv::Size(head.width / 2, head.height / 4), 0.0, hair);
  for (const int ex : {head.width / 3, head.width * 2 / 3}) {
    p.disk(cv::Point(head.x + ex, head.y + head.height / 2), std::max(1, w / 40), r.gray(0, 50));
  }
  paintGarment(p, cv::Rect(box.x, box.y + h * 14 / 100, w, h * 38 / 100));  // top
  paintGarment(p, cv::Rect(box.x + w / 10, box.y + h * 52 / 100, w * 8 / 10, h * 43 / 100));
  p.fill(cv::Rect(box.x + w / 2 - 1, box.y + h * 60 / 100, 2, h * 35 / 100), r.gray(0, 60));
  p.fill(cv::Rect(box.x + w / 10, box.y + h * 95 / 100, w * 8 / 10, h * 5 / 100), r.gray(0, 80));
  if (r.chance(0.3)) {  // backpack or bag strap
    p.line(cv::Point(box.x + w / 5, box.y + h * 14 / 100),
           cv::Point(box.x + w * 4 / 5, box.y + h * 45 / 100), std::max(1, w / 15), r.gray(0, 255));
  }
}

StyleLook paintPedestrian(Painter& p) {
  Random& r = p.random();
  p.canvas().setTo(r.gray(30, 200));
  for (int y = 0; y < p.rows();) {
    const int h = p.texels(1.55, 1.95);
    for (int x = r.uniformInt(-p.texels(0.3), 0); x < p.cols();) {
      const int w = p.texels(0.45, 0.65);
      paintPerson(p, cv::Rect(x, y, w, h));
      x += w;
    }
    y += h;
  }
  return {
      .noise_gray = 5.0, .stain_gray = 5.0, .target_mean = r.uniform(95, 135), .target_std = 55.0};
}

StyleLook paintStyle(TextureStyle style, Painter& painter) {
  switch (style) {
    case TextureStyle::kGround:
      return paintGround(painter);
    case TextureStyle::kFacade:
      return paintFacade(painter);
    case TextureStyle::kIndoor:
      return paintIndoor(painter);
    case TextureStyle::kVehicle:
      return paintVehicle(painter);
    case TextureStyle::kPedestrian:
      return paintPedestrian(painter);
  }
  return paintGround(painter);
}

// ------------------------------------------------------------------------------------------------
// Fractal noise and finishing

/// Zero-mean, unit-std fractal Brownian noise of `size` built coarse to fine: each octave
/// upsamples the sum so far by 2 (bicubic) and adds fresh white noise, so the total costs about
/// 4/3 of one upsampling to the finest grid. Octaves have periods from 2 texels (finest) to
/// `coarsest_period` texels; amplitude grows with the period as period^hurst.
cv::Mat fractalNoise(cv::Size size, double coarsest_period, double hurst, cv::RNG& rng) {
  const int octaves =
      std::max(1, static_cast<int>(std::ceil(std::log2(std::max(2.0, coarsest_period) / 2.0))));
  const auto gridAt = [&](int octave) {  // grid of the octave with period 2^(octave+1) texels
    const double period = std::ldexp(1.0, octave + 1);
    return cv::Size(static_cast<int>(std::ceil(size.width / period)) + 1,
                    static_cast<int>(std::ceil(size.height / period)) + 1);
  };
  cv::Mat sum(gridAt(octaves - 1), CV_32F);
  rng.fill(sum, cv::RNG::NORMAL, 0.0, 1.0);
  for (int octave = octaves - 2; octave >= 0; --octave) {
    cv::Mat finer;
    cv::resize(sum, finer, gridAt(octave), 0.0, 0.0, cv::INTER_CUBIC);
    cv::Mat fresh(finer.size(), CV_32F);
    // Relative amplitude of this octave against the coarser ones: 2^-hurst per octave.
    const double amplitude = std::pow(2.0, -hurst * (octaves - 1 - octave));
    rng.fill(fresh, cv::RNG::NORMAL, 0.0, amplitude);
    sum = finer + fresh;
  }
  cv::Scalar mean, stddev;
  cv::meanStdDev(sum, mean, stddev);
  sum = (sum - mean[0]) / std::max(1e-6, stddev[0]);
  cv::Mat full;
  cv::resize(sum, full, size, 0.0, 0.0, cv::INTER_LINEAR);
  return full;
}

/// Adds weathering to the structure layer: fractal noise (dirt, shading, material grain) and
/// stains with sharp edges where a second, rougher noise crosses thresholds.
void addWeathering(cv::Mat& radiance, const StyleLook& look, double texel_m, Random& random) {
  cv::RNG rng(random.bits());
  const double coarsest = std::min(4.0 / texel_m, 2.0 * std::max(radiance.cols, radiance.rows));
  radiance += fractalNoise(radiance.size(), coarsest, 0.7, rng) * look.noise_gray;
  const cv::Mat stains = fractalNoise(radiance.size(), std::min(coarsest, 0.5 / texel_m), 0.3, rng);
  cv::add(radiance, cv::Scalar(look.stain_gray), radiance, stains > 1.0);
  cv::subtract(radiance, cv::Scalar(look.stain_gray), radiance, stains < -1.2);
}

/// Linear contrast stretch to the style's mean and std, saturated to 8 bits.
cv::Mat finishContrast(const cv::Mat& radiance, const StyleLook& look) {
  cv::Scalar mean, stddev;
  cv::meanStdDev(radiance, mean, stddev);
  const double scale = stddev[0] > 1e-3 ? look.target_std / stddev[0] : 1.0;
  cv::Mat gray;
  radiance.convertTo(gray, CV_8U, scale, look.target_mean - scale * mean[0]);
  return gray;
}

// ------------------------------------------------------------------------------------------------
// Photos

cv::Mat toGray8(const cv::Mat& image) {
  cv::Mat gray = image;
  if (image.channels() == 3) cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  if (image.channels() == 4) cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  if (gray.channels() != 1) throw OptionError("image", "must have 1, 3 or 4 channels");
  cv::Mat out;
  switch (gray.depth()) {
    case CV_8U:
      out = gray.clone();
      break;
    case CV_16U:
      gray.convertTo(out, CV_8U, 1.0 / 256.0);
      break;
    default:
      gray.convertTo(out, CV_8U);
      break;
  }
  return out;
}

/// Splits `box` recursively into random rectangles with sides in [min_side, 2 * min_side)
/// texels or smaller at the borders, so the mosaic has no grid.
void splitMosaic(const cv::Rect& box, int min_side, Random& random, std::vector<cv::Rect>& cells) {
  const bool split_x =
      box.width >= 2 * min_side && (box.width >= box.height || box.height < 2 * min_side);
  const bool split_y = !split_x && box.height >= 2 * min_side;
  if (!split_x && !split_y) {
    cells.push_back(box);
    return;
  }
  const int extent = split_x ? box.width : box.height;
  const int cut = random.uniformInt(min_side, extent - min_side);
  if (split_x) {
    splitMosaic(cv::Rect(box.x, box.y, cut, box.height), min_side, random, cells);
    splitMosaic(cv::Rect(box.x + cut, box.y, box.width - cut, box.height), min_side, random, cells);
  } else {
    splitMosaic(cv::Rect(box.x, box.y, box.width, cut), min_side, random, cells);
    splitMosaic(cv::Rect(box.x, box.y + cut, box.width, box.height - cut), min_side, random, cells);
  }
}

/// Fills `cell` of `canvas` with a random crop of `photo`, scaled by 0.5..2 and maybe mirrored.
void fillWithCrop(const cv::Mat& photo, cv::Mat& canvas, const cv::Rect& cell, Random& random) {
  const double scale = std::exp(random.uniform(std::log(0.5), std::log(2.0)));
  const int crop_w = std::clamp(static_cast<int>(cell.width / scale), 1, photo.cols);
  const int crop_h = std::clamp(static_cast<int>(cell.height / scale), 1, photo.rows);
  const int crop_y = random.uniformInt(0, photo.rows - crop_h);
  const cv::Rect crop(random.uniformInt(0, photo.cols - crop_w), crop_y, crop_w, crop_h);
  cv::Mat patch;
  cv::resize(photo(crop), patch, cell.size(), 0.0, 0.0,
             crop_w > cell.width ? cv::INTER_AREA : cv::INTER_LINEAR);
  if (random.chance(0.5)) cv::flip(patch, patch, 1);
  patch.copyTo(canvas(cell));
}

void requirePositive(double value, const char* name) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw OptionError(name, "must be a positive finite number");
  }
}

void requireSize(int value, const char* name) {
  if (value < 1 || value > kMaxTextureSize) {
    throw OptionError(name, fmt::format("must be in [1, {}], got {}", kMaxTextureSize, value));
  }
}

/// floor() for |x| < 2^62, without a library call in the per-pixel path.
inline std::int64_t floorToInt(double x) {
  const auto truncated = static_cast<std::int64_t>(x);
  return truncated - (x < static_cast<double>(truncated) ? 1 : 0);
}

/// Index of a texel along an axis of n texels, wrapping around (the common in-range case
/// without a division).
inline int wrapIndex(std::int64_t i, int n) {
  if (i >= 0 && i < n) return static_cast<int>(i);
  i %= n;
  return static_cast<int>(i < 0 ? i + n : i);
}

}  // namespace

std::string toString(TextureStyle style) {
  switch (style) {
    case TextureStyle::kGround:
      return "ground";
    case TextureStyle::kFacade:
      return "facade";
    case TextureStyle::kIndoor:
      return "indoor";
    case TextureStyle::kVehicle:
      return "vehicle";
    case TextureStyle::kPedestrian:
      return "pedestrian";
  }
  return "unknown";
}

void ProceduralTextureOptions::validate() const {
  requireSize(width, "width");
  requireSize(height, "height");
  requirePositive(texel_m, "texel_m");
  switch (style) {
    case TextureStyle::kGround:
    case TextureStyle::kFacade:
    case TextureStyle::kIndoor:
    case TextureStyle::kVehicle:
    case TextureStyle::kPedestrian:
      return;
  }
  throw OptionError("style", "unknown texture style");
}

Texture::Texture() : Texture(cv::Mat(1, 1, CV_8UC1, cv::Scalar(128)), 1.0) {}

Texture::Texture(cv::Mat image, double texel_m) : texel_m_(texel_m) {
  // Each level spans the same surface: its texel size is the extent over its texel count.
  const Eigen::Vector2d extent_m(image.cols * texel_m, image.rows * texel_m);
  levels_.push_back(std::move(image));
  while (levels_.back().cols > 1 || levels_.back().rows > 1) {
    const cv::Mat& finer = levels_.back();
    cv::Mat coarser;
    cv::resize(finer, coarser, cv::Size((finer.cols + 1) / 2, (finer.rows + 1) / 2), 0.0, 0.0,
               cv::INTER_AREA);
    levels_.push_back(std::move(coarser));
  }
  for (const cv::Mat& level : levels_) {
    level_texels_per_m_.emplace_back(level.cols / extent_m.x(), level.rows / extent_m.y());
  }
}

Texture Texture::fromImage(const cv::Mat& image, double texel_m) {
  if (image.empty()) throw OptionError("image", "is empty");
  requirePositive(texel_m, "texel_m");
  return Texture(toGray8(image), texel_m);
}

Texture Texture::uniform(double gray_level) {
  return Texture(cv::Mat(1, 1, CV_8UC1, cv::Scalar(std::clamp(std::round(gray_level), 0.0, 255.0))),
                 1.0);
}

Texture Texture::procedural(const ProceduralTextureOptions& options) {
  options.validate();
  Random random(mix64(options.seed ^ (static_cast<std::uint64_t>(options.style) << 56)));
  cv::Mat structure(options.height, options.width, CV_8UC1);
  Painter painter(structure, options.texel_m, random);
  const StyleLook look = paintStyle(options.style, painter);
  cv::Mat radiance;
  structure.convertTo(radiance, CV_32F);
  structure.release();
  addWeathering(radiance, look, options.texel_m, random);
  return Texture(finishContrast(radiance, look), options.texel_m);
}

Texture Texture::fromPhotos(const std::vector<cv::Mat>& photos, int width, int height,
                            double texel_m, std::uint64_t seed) {
  requireSize(width, "width");
  requireSize(height, "height");
  requirePositive(texel_m, "texel_m");
  std::vector<cv::Mat> grays;
  for (const cv::Mat& photo : photos) {
    if (!photo.empty()) grays.push_back(toGray8(photo));
  }
  if (grays.empty()) throw OptionError("photos", "no non-empty photo given");
  Random random(mix64(seed));
  std::vector<cv::Rect> cells;
  // Cells of 1/4 to 1/2 of a typical photo keep crops large enough to look natural.
  const int min_side = std::max(16, std::min(grays.front().cols, grays.front().rows) / 4);
  splitMosaic(cv::Rect(0, 0, width, height), min_side, random, cells);
  cv::Mat canvas(height, width, CV_8UC1);
  for (const cv::Rect& cell : cells) {
    const auto pick =
        static_cast<std::size_t>(random.uniformInt(0, static_cast<int>(grays.size()) - 1));
    fillWithCrop(grays[pick], canvas, cell, random);
  }
  return Texture(std::move(canvas), texel_m);
}

Texture Texture::withContrast(double factor) const {
  if (!(factor > 0.0 && factor <= 4.0)) {
    throw OptionError("contrast", fmt::format("must be in (0, 4], got {}", factor));
  }
  if (factor == 1.0) return *this;
  const double mean = cv::mean(levels_.front())[0];
  cv::Mat scaled;
  levels_.front().convertTo(scaled, CV_8UC1, factor, (1.0 - factor) * mean);
  return Texture(std::move(scaled), texel_m_);
}

float Texture::bilinear(std::size_t level, double u_m, double v_m) const {
  const cv::Mat& image = levels_[level];
  const double x = u_m * level_texels_per_m_[level].x() - 0.5;
  const double y = v_m * level_texels_per_m_[level].y() - 0.5;
  const std::int64_t x_floor = floorToInt(x), y_floor = floorToInt(y);
  const auto wx = static_cast<float>(x - static_cast<double>(x_floor));
  const auto wy = static_cast<float>(y - static_cast<double>(y_floor));
  const int c0 = wrapIndex(x_floor, image.cols), r0 = wrapIndex(y_floor, image.rows);
  const int c1 = c0 + 1 == image.cols ? 0 : c0 + 1;
  const int r1 = r0 + 1 == image.rows ? 0 : r0 + 1;
  const std::uint8_t* row0 = image.ptr<std::uint8_t>(r0);
  const std::uint8_t* row1 = image.ptr<std::uint8_t>(r1);
  const float top = row0[c0] + wx * (static_cast<float>(row0[c1]) - row0[c0]);
  const float bottom = row1[c0] + wx * (static_cast<float>(row1[c1]) - row1[c0]);
  return top + wy * (bottom - top);
}

float Texture::sample(const Eigen::Vector2d& uv_m, double footprint_m) const {
  // Far-away coordinates would overflow the texel index; wrap them into one period first.
  constexpr double kLargeM = 1e9;
  double u = uv_m.x(), v = uv_m.y();
  if (!std::isfinite(u) || !std::isfinite(v)) return bilinear(0, 0.0, 0.0);
  if (std::abs(u) > kLargeM) u = std::fmod(u, widthM());
  if (std::abs(v) > kLargeM) v = std::fmod(v, heightM());
  const double lod = footprint_m > texel_m_ ? std::log2(footprint_m / texel_m_) : 0.0;
  const double last = static_cast<double>(levels_.size() - 1);
  if (!(lod > 0.0)) return bilinear(0, u, v);
  if (lod >= last) return bilinear(levels_.size() - 1, u, v);
  const double lod_floor = std::floor(lod);
  const auto level = static_cast<std::size_t>(lod_floor);
  const auto blend = static_cast<float>(lod - lod_floor);
  const float fine = bilinear(level, u, v);
  return fine + blend * (bilinear(level + 1, u, v) - fine);
}

}  // namespace superdyna::sim
