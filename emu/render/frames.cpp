#include "frames.hpp"

#include <fmt/format.h>
#include <png.h>
#include <spawn.h>
#include <sys/wait.h>

#include <cerrno>
#include <cstring>
#include <regex>

#include "mrroc/core/error.hpp"

extern char** environ;

namespace mrroc::render {

void write_png(const std::filesystem::path& file, const std::vector<std::uint8_t>& rgb, int width,
               int height) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(width);
  image.height = static_cast<png_uint_32>(height);
  image.format = PNG_FORMAT_RGB;
  image.flags = PNG_IMAGE_FLAG_FAST;  // quicker compression, somewhat larger files
  if (png_image_write_to_file(&image, file.c_str(), 0, rgb.data(), width * 3, nullptr) == 0) {
    const std::string reason = image.message;
    png_image_free(&image);
    throw Error(fmt::format("cannot write the image '{}': {}", file.string(), reason));
  }
}

std::string frame_name(std::size_t number) { return fmt::format("frame_{:05d}.png", number); }

std::size_t remove_old_frames(const std::filesystem::path& dir) {
  static const std::regex pattern("frame_[0-9]{5}\\.png");
  std::size_t removed = 0;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    if (entry.is_regular_file() && std::regex_match(entry.path().filename().string(), pattern)) {
      std::filesystem::remove(entry.path(), ec);
      if (!ec) ++removed;
    }
  }
  return removed;
}

void encode_video(const std::string& ffmpeg, const std::filesystem::path& dir, double fps,
                  const std::filesystem::path& video) {
  std::vector<std::string> args = {
      ffmpeg, "-nostdin", "-hide_banner", "-loglevel", "error", "-y", "-framerate",
      fmt::format("{}", fps), "-i", (dir / kFramePattern).string(),
      // H.264 in yuv420p needs even sizes.
      "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-c:v", "libx264", "-pix_fmt", "yuv420p", "-movflags",
      "+faststart", video.string()};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int spawned = posix_spawnp(&pid, ffmpeg.c_str(), nullptr, nullptr, argv.data(), environ);
  if (spawned != 0) {
    throw Error(
        fmt::format("cannot start ffmpeg '{}': {} (Debian package ffmpeg; or leave the "
                    "video out with --no-video)",
                    ffmpeg, std::strerror(spawned)));
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) throw Error(fmt::format("waiting for ffmpeg: {}", std::strerror(errno)));
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    throw Error(fmt::format("ffmpeg '{}' failed ({}) making '{}' from the frames in '{}'", ffmpeg,
                            WIFEXITED(status) ? fmt::format("exit status {}", WEXITSTATUS(status))
                                              : fmt::format("signal {}", WTERMSIG(status)),
                            video.string(), dir.string()));
  }
}

}  // namespace mrroc::render
