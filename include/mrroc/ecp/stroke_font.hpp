#pragma once
/// @file
/// The stroke font of the engraving task (ecp/tasks/engrave.cpp) and how a text is laid out on the
/// board: one definition of the letters for the task that cuts them and the tests that measure
/// the grooves.
///
/// A letter is a list of strokes, each a polyline in the letter's unit box (u along the text,
/// v up the letter, both 0 .. 1). A text is laid out from `origin` (its lower-left corner on the
/// board's surface, in the robot's base frame [m]): letter i starts at u0 = i (width + spacing)
/// along +y, and the letters stand upright along -x (read from the robot's side of the board):
/// the unit point (u, v) of letter i is origin + (-v height, u0 + u width, 0). A space takes a
/// letter's place and has no strokes.
#include <Eigen/Core>
#include <cmath>
#include <map>
#include <numbers>
#include <string>
#include <vector>

namespace mrroc::ecp::engraving {

/// A stroke in a letter's unit box: (u along the text, v up the letter).
using Stroke = std::vector<Eigen::Vector2d>;

/// The letters of the font, for messages.
inline constexpr const char* kFontLetters = "C, M, O, R, space";

/// An arc of the circle inscribed in the unit box, from `from_deg` to `to_deg` in `pieces` lines.
inline Stroke arc_stroke(double from_deg, double to_deg, int pieces) {
  Stroke s;
  for (int i = 0; i <= pieces; ++i) {
    const double a = (from_deg + (to_deg - from_deg) * i / pieces) * std::numbers::pi / 180.0;
    s.emplace_back(0.5 + 0.5 * std::cos(a), 0.5 + 0.5 * std::sin(a));
  }
  return s;
}

/// The strokes of letter `c`, in cutting order; nullptr for a letter the font lacks (and ' ').
inline const std::vector<Stroke>* letter_strokes(char c) {
  static const std::map<char, std::vector<Stroke>> font = {
      {'M', {{{0, 0}, {0, 1}, {0.5, 0.45}, {1, 1}, {1, 0}}}},
      {'R',
       {{{0, 0}, {0, 1}, {0.7, 1}, {1, 0.85}, {1, 0.65}, {0.7, 0.5}, {0, 0.5}},
        {{0.45, 0.5}, {1, 0}}}},
      {'O', {arc_stroke(0, 360, 12)}},
      {'C', {arc_stroke(45, 315, 9)}},
  };
  const auto it = font.find(c);
  return it == font.end() ? nullptr : &it->second;
}

/// Whether every character of `text` is a letter of the font or a space.
inline bool in_font(const std::string& text) {
  for (const char c : text)
    if (c != ' ' && letter_strokes(c) == nullptr) return false;
  return true;
}

/// Where a text goes on the board [m].
struct TextLayout {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  ///< lower-left corner on the surface
  double letter_height = 0.04;
  double letter_width = 0.03;
  double spacing = 0.012;  ///< between letters
};

/// The unit point `p` of the `index`-th character of the text, on the surface [m].
inline Eigen::Vector3d place(const TextLayout& layout, int index, const Eigen::Vector2d& p) {
  const double u0 = index * (layout.letter_width + layout.spacing);
  return layout.origin +
         Eigen::Vector3d(-p.y() * layout.letter_height, u0 + p.x() * layout.letter_width, 0.0);
}

/// Every stroke of `text` in cutting order, as polylines on the surface [m] (letters the font
/// lacks are skipped: check in_font() first).
inline std::vector<std::vector<Eigen::Vector3d>> text_strokes(const std::string& text,
                                                              const TextLayout& layout) {
  std::vector<std::vector<Eigen::Vector3d>> out;
  int index = 0;
  for (const char c : text) {
    const std::vector<Stroke>* strokes = letter_strokes(c);
    if (strokes != nullptr) {
      for (const Stroke& stroke : *strokes) {
        std::vector<Eigen::Vector3d> line;
        for (const Eigen::Vector2d& p : stroke) line.push_back(place(layout, index, p));
        out.push_back(std::move(line));
      }
    }
    ++index;
  }
  return out;
}

}  // namespace mrroc::ecp::engraving
