#include "offscreen.hpp"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cstring>

#include "mrroc/core/error.hpp"

namespace mrroc::render {

namespace {

const char* egl_error_name(EGLint error) {
  switch (error) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    case EGL_BAD_SURFACE: return "EGL_BAD_SURFACE";
    default: return "unknown EGL error";
  }
}

std::string egl_failure(const char* what) {
  const EGLint error = eglGetError();
  return fmt::format(
      "no OpenGL for off-screen drawing: {} failed ({} 0x{:04X}); Mesa's EGL "
      "(Debian packages libegl1, libegl-mesa0, libgl1-mesa-dri) draws without a "
      "display or GPU",
      what, egl_error_name(error), error);
}

bool has_extension(const char* list, const char* name) {
  if (list == nullptr) return false;
  const std::size_t n = std::strlen(name);
  for (const char* p = std::strstr(list, name); p != nullptr; p = std::strstr(p + 1, name)) {
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  }
  return false;
}

}  // namespace

GlContext::GlContext() {
  // Mesa's surfaceless platform needs neither X nor a GPU (llvmpipe draws in software).
  const char* client_extensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  EGLDisplay display = EGL_NO_DISPLAY;
  std::string platform = "default display";
  if (has_extension(client_extensions, "EGL_MESA_platform_surfaceless")) {
    const auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
        eglGetProcAddress("eglGetPlatformDisplayEXT"));
    if (get_platform_display != nullptr) {
      display = get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
      platform = "surfaceless platform";
    }
  }
  if (display == EGL_NO_DISPLAY) {
    display = eglGetDisplay(EGL_DEFAULT_DISPLAY);
    platform = "default display";
  }
  if (display == EGL_NO_DISPLAY) throw Error(egl_failure("eglGetDisplay"));
  EGLint major = 0;
  EGLint minor = 0;
  if (eglInitialize(display, &major, &minor) != EGL_TRUE) {
    throw Error(egl_failure(fmt::format("eglInitialize on the {}", platform).c_str()));
  }
  display_ = display;
  const std::array<EGLint, 15> attributes = {EGL_SURFACE_TYPE,
                                             EGL_PBUFFER_BIT,
                                             EGL_RED_SIZE,
                                             8,
                                             EGL_GREEN_SIZE,
                                             8,
                                             EGL_BLUE_SIZE,
                                             8,
                                             EGL_DEPTH_SIZE,
                                             24,
                                             EGL_STENCIL_SIZE,
                                             8,
                                             EGL_RENDERABLE_TYPE,
                                             EGL_OPENGL_BIT,
                                             EGL_NONE};
  EGLConfig config = nullptr;
  EGLint configs = 0;
  if (eglChooseConfig(display, attributes.data(), &config, 1, &configs) != EGL_TRUE ||
      configs < 1) {
    eglTerminate(display);
    display_ = nullptr;
    throw Error(egl_failure(
        fmt::format("eglChooseConfig (desktop OpenGL, RGB 8 bits, depth 24 bits) on the {}",
                    platform)
            .c_str()));
  }
  if (eglBindAPI(EGL_OPENGL_API) != EGL_TRUE) {
    eglTerminate(display);
    display_ = nullptr;
    throw Error(egl_failure("eglBindAPI(EGL_OPENGL_API)"));
  }
  EGLContext context = eglCreateContext(display, config, EGL_NO_CONTEXT, nullptr);
  if (context == EGL_NO_CONTEXT) {
    eglTerminate(display);
    display_ = nullptr;
    throw Error(egl_failure("eglCreateContext (desktop OpenGL)"));
  }
  context_ = context;
  // No surface: MuJoCo draws into a framebuffer object of its own.
  if (eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context) != EGL_TRUE) {
    const std::string message = egl_failure("eglMakeCurrent without a surface");
    eglDestroyContext(display, context);
    eglTerminate(display);
    context_ = nullptr;
    display_ = nullptr;
    throw Error(message);
  }
  using GetString = const unsigned char* (*)(unsigned int);
  const auto get_string = reinterpret_cast<GetString>(eglGetProcAddress("glGetString"));
  const auto text = [&](unsigned int name) -> std::string {
    const unsigned char* s = get_string != nullptr ? get_string(name) : nullptr;
    return s != nullptr ? reinterpret_cast<const char*>(s) : "?";
  };
  constexpr unsigned int kGlRenderer = 0x1F01;  // GL_RENDERER
  constexpr unsigned int kGlVersion = 0x1F02;   // GL_VERSION
  description_ = fmt::format("EGL {}.{} on the {}; OpenGL {}, {}", major, minor, platform,
                             text(kGlVersion), text(kGlRenderer));
}

GlContext::~GlContext() {
  if (display_ != nullptr) {
    eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (context_ != nullptr) eglDestroyContext(display_, context_);
    eglTerminate(display_);
  }
}

Renderer::Renderer(mjModel* model, int width, int height)
    : model_(model), width_(width), height_(height) {
  model->vis.global.offwidth = width;
  model->vis.global.offheight = height;
  mjv_defaultScene(&scene_);
  mjv_makeScene(model, &scene_, 10000);
  mjv_defaultOption(&option_);
  mjv_defaultCamera(&camera_);
  camera_.type = mjCAMERA_FREE;
  mjr_defaultContext(&context_);
  mjr_makeContext(model, &context_, mjFONTSCALE_150);
  mjr_setBuffer(mjFB_OFFSCREEN, &context_);
  if (context_.currentBuffer != mjFB_OFFSCREEN || context_.offWidth < width ||
      context_.offHeight < height) {
    const int got_width = context_.offWidth;
    const int got_height = context_.offHeight;
    mjr_freeContext(&context_);
    mjv_freeScene(&scene_);
    throw Error(
        fmt::format("MuJoCo cannot draw off-screen at {} x {} pixels (its off-screen "
                    "buffer is {} x {})",
                    width, height, got_width, got_height));
  }
  const auto bytes = static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 3;
  flipped_.resize(bytes);
  image_.resize(bytes);
}

Renderer::~Renderer() {
  mjr_freeContext(&context_);
  mjv_freeScene(&scene_);
}

const std::vector<std::uint8_t>& Renderer::draw(const mjData* data, const CameraView& view,
                                                const std::string& label) {
  std::copy(view.lookat, view.lookat + 3, camera_.lookat);
  camera_.distance = view.distance;
  camera_.azimuth = view.azimuth;
  camera_.elevation = view.elevation;
  // mjv_updateScene takes the data as non-const but only reads it.
  mjv_updateScene(model_, const_cast<mjData*>(data), &option_, nullptr, &camera_, mjCAT_ALL,
                  &scene_);
  const mjrRect viewport{0, 0, width_, height_};
  mjr_render(viewport, &scene_, &context_);
  if (!label.empty()) {
    mjr_overlay(mjFONT_NORMAL, mjGRID_TOPLEFT, viewport, label.c_str(), nullptr, &context_);
  }
  mjr_readPixels(flipped_.data(), nullptr, viewport, &context_);
  // OpenGL's rows start at the bottom; images' at the top.
  const auto row = static_cast<std::size_t>(width_) * 3;
  for (std::size_t y = 0; y < static_cast<std::size_t>(height_); ++y) {
    std::copy_n(flipped_.data() + (static_cast<std::size_t>(height_) - 1 - y) * row, row,
                image_.data() + y * row);
  }
  return image_;
}

}  // namespace mrroc::render
