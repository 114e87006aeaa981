#pragma once
// What mrroc-render writes: PNG images (libpng) and an MP4 video made of them by ffmpeg, run as
// a child process.

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace mrroc::render {

/// Writes an RGB image (rows from the top, 3 bytes a pixel) as a PNG file.
/// @throws Error naming the file and libpng's reason.
void write_png(const std::filesystem::path& file, const std::vector<std::uint8_t>& rgb, int width,
               int height);

/// The file name of frame `number` ("frame_00042.png"); kFramePattern is its printf pattern.
std::string frame_name(std::size_t number);
inline constexpr const char* kFramePattern = "frame_%05d.png";

/// Removes the frame files (frame_NNNNN.png) a former run left in `dir`, so that a shorter run
/// does not make a video with old frames at its end. Returns how many it removed.
std::size_t remove_old_frames(const std::filesystem::path& dir);

/// Makes an H.264 MP4 (yuv420p, plays everywhere) of the frames frame_00000.png ... in `dir` at
/// `fps` frames a second with `ffmpeg` (a path, or a name looked up in PATH).
/// @throws Error when ffmpeg cannot be started (naming it and the Debian package) or fails
///   (naming its exit status; its own message is on stderr above).
void encode_video(const std::string& ffmpeg, const std::filesystem::path& dir, double fps,
                  const std::filesystem::path& video);

}  // namespace mrroc::render
