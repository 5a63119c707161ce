#pragma once
// Checks of a frame image's header before OpenCV decodes it (internal to src/io): the size a file
// declares is compared with what the sonar expects before any pixel memory is allocated, and a
// PNG's chunk structure and CRCs are verified so that libpng never prints its own multi-line
// errors on stderr for a corrupt file (the error is one line naming the file instead).
#include <string>

namespace sonar3d::detail {

struct ImageHeader {
  bool known = false;  // false: neither PNG nor TIFF, left to OpenCV
  int width = 0, height = 0;
  int bit_depth = 0;  // bits per sample
  int channels = 0;
  bool is_float = false;
};

// Reads the header of a PNG or TIFF file; throws Error naming `path` when the file is corrupt
// (bad magic, truncated or inconsistent chunks, bad CRC, interlaced PNG).
ImageHeader read_image_header(const std::string& path);

}  // namespace sonar3d::detail
