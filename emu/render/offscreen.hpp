#pragma once
// Off-screen OpenGL for MuJoCo's renderer without a display: an EGL context on Mesa's
// surfaceless platform (software rendering by llvmpipe when there is no GPU), or on EGL's default
// display when that platform is missing. MuJoCo draws into its own off-screen framebuffer.

#include <cstdint>
#include <string>
#include <vector>

#include <mujoco/mujoco.h>

namespace mrroc::render {

/// A current OpenGL context made with EGL (no window, no surface).
class GlContext {
 public:
  /// @throws Error "no OpenGL for off-screen drawing: ..." naming what failed (EGL's display,
  ///   a configuration, the context) and the EGL error, and the Debian packages that provide it.
  GlContext();
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  /// "EGL platform surfaceless; OpenGL 4.5 (Compatibility Profile) Mesa 22.3.6, llvmpipe (...)".
  [[nodiscard]] const std::string& description() const noexcept { return description_; }

 private:
  void* display_ = nullptr;
  void* context_ = nullptr;
  std::string description_;
};

/// Where the camera looks from: a free camera around a point.
struct CameraView {
  double lookat[3] = {0.0, 0.0, 0.0};  ///< [m], world frame
  double distance = 3.0;               ///< [m]
  double azimuth = 135.0;              ///< [deg], about the world z axis
  double elevation = -20.0;            ///< [deg], negative: from above
};

/// MuJoCo's renderer of one model into an RGB image of a fixed size (needs a current GlContext).
class Renderer {
 public:
  /// Sets the model's off-screen buffer size to width x height (pixels) and makes MuJoCo's
  /// rendering context. @throws Error when MuJoCo cannot draw off-screen at that size.
  Renderer(mjModel* model, int width, int height);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  /// Draws the model in the state `data` seen from `view` (with `label` in the top left corner
  /// when not empty) and returns the image, RGB, rows from the top.
  const std::vector<std::uint8_t>& draw(const mjData* data, const CameraView& view,
                                        const std::string& label);

  [[nodiscard]] int width() const noexcept { return width_; }
  [[nodiscard]] int height() const noexcept { return height_; }

 private:
  const mjModel* model_;
  int width_;
  int height_;
  mjvScene scene_{};
  mjvOption option_{};
  mjvCamera camera_{};
  mjrContext context_{};
  std::vector<std::uint8_t> flipped_;
  std::vector<std::uint8_t> image_;
};

}  // namespace mrroc::render
