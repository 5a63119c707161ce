#include "image_header.hpp"

#include <array>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <vector>

#include "sonar3d/core/error.hpp"

namespace sonar3d::detail {
namespace {

uint32_t crc32(const unsigned char* p, std::size_t n, uint32_t crc = 0) {
  static const std::array<uint32_t, 256> table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  crc = ~crc;
  for (std::size_t i = 0; i < n; ++i) crc = table[(crc ^ p[i]) & 0xFF] ^ (crc >> 8);
  return ~crc;
}

uint32_t be32(const unsigned char* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | p[3];
}

ImageHeader png_header(std::ifstream& f, const std::string& path) {
  auto fail = [&](const std::string& what) {
    throw Error("cannot decode image '" + path + "': corrupt PNG (" + what + ")");
  };
  ImageHeader h;
  h.known = true;
  bool first = true, have_idat = false, have_iend = false;
  std::vector<unsigned char> buf;
  while (!have_iend) {
    unsigned char head[8];
    if (!f.read(reinterpret_cast<char*>(head), 8)) fail("truncated: no IEND chunk");
    const uint32_t len = be32(head);
    if (len > 0x7FFFFFFFu) fail("chunk length out of range");
    for (int k = 4; k < 8; ++k) {
      const unsigned char c = head[k];
      if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z'))) fail("invalid chunk type");
    }
    const std::string type(reinterpret_cast<const char*>(head + 4), 4);
    if (first && type != "IHDR") fail("the first chunk is not IHDR");
    // Read the chunk in bounded pieces (a claimed length beyond the file fails at the read).
    uint32_t crc = crc32(head + 4, 4);
    std::vector<unsigned char> ihdr;
    for (uint32_t left = len; left > 0;) {
      const uint32_t n = std::min<uint32_t>(left, 1u << 16);
      buf.resize(n);
      if (!f.read(reinterpret_cast<char*>(buf.data()), n)) fail("truncated chunk " + type);
      crc = crc32(buf.data(), n, crc);
      if (first) ihdr.insert(ihdr.end(), buf.begin(), buf.end());
      left -= n;
    }
    unsigned char tail[4];
    if (!f.read(reinterpret_cast<char*>(tail), 4)) fail("truncated chunk " + type);
    if (be32(tail) != crc) fail("CRC error in chunk " + type);
    if (first) {
      if (len != 13) fail("IHDR has the wrong length");
      h.width = static_cast<int>(std::min<uint32_t>(be32(ihdr.data()), 0x7FFFFFFF));
      h.height = static_cast<int>(std::min<uint32_t>(be32(ihdr.data() + 4), 0x7FFFFFFF));
      h.bit_depth = ihdr[8];
      const int color = ihdr[9];
      h.channels = color == 0 ? 1 : color == 2 ? 3 : color == 3 ? 1 : color == 4 ? 2 : 4;
      if (color == 3) h.channels = 3;  // palette: decoded as colour
      if (ihdr[12] != 0) fail("interlaced PNG frames are not supported");
      if (h.width == 0 || h.height == 0) fail("zero width or height");
    }
    if (type == "IDAT") have_idat = true;
    if (type == "IEND") have_iend = true;
    first = false;
  }
  if (!have_idat) fail("no IDAT chunk");
  return h;
}

ImageHeader tiff_header(std::ifstream& f, const std::string& path, bool little) {
  auto fail = [&](const std::string& what) {
    throw Error("cannot decode image '" + path + "': corrupt TIFF (" + what + ")");
  };
  auto u16 = [&](const unsigned char* p) {
    return little ? static_cast<uint32_t>(p[0] | (p[1] << 8))
                  : static_cast<uint32_t>((p[0] << 8) | p[1]);
  };
  auto u32 = [&](const unsigned char* p) {
    return little ? (uint32_t{p[0]} | (uint32_t{p[1]} << 8) | (uint32_t{p[2]} << 16) |
                     (uint32_t{p[3]} << 24))
                  : be32(p);
  };
  unsigned char off[4];
  if (!f.read(reinterpret_cast<char*>(off), 4)) fail("truncated header");
  f.seekg(u32(off));
  unsigned char cnt[2];
  if (!f.read(reinterpret_cast<char*>(cnt), 2)) fail("the first directory is outside the file");
  const uint32_t n = u16(cnt);
  ImageHeader h;
  h.known = true;
  h.bit_depth = 1;
  h.channels = 1;
  for (uint32_t i = 0; i < n; ++i) {
    unsigned char e[12];
    if (!f.read(reinterpret_cast<char*>(e), 12)) fail("truncated directory");
    const uint32_t tag = u16(e), type = u16(e + 2), count = u32(e + 4);
    // Inline SHORT or LONG values (tags read here hold one value).
    const uint32_t value = type == 3 ? u16(e + 8) : u32(e + 8);
    if (count != 1 && tag != 258) continue;
    if (tag == 256) h.width = static_cast<int>(std::min<uint32_t>(value, 0x7FFFFFFF));
    if (tag == 257) h.height = static_cast<int>(std::min<uint32_t>(value, 0x7FFFFFFF));
    if (tag == 258 && count <= 2) h.bit_depth = static_cast<int>(value);
    if (tag == 277) h.channels = static_cast<int>(value);
    if (tag == 339) h.is_float = value == 3;
  }
  if (h.width <= 0 || h.height <= 0) fail("no image width or height");
  return h;
}

}  // namespace

ImageHeader read_image_header(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error("cannot open image '" + path + "'");
  unsigned char magic[8] = {};
  f.read(reinterpret_cast<char*>(magic), 8);
  if (f.gcount() == 8 && std::memcmp(magic, "\x89PNG\r\n\x1a\n", 8) == 0) {
    return png_header(f, path);
  }
  if (f.gcount() >= 4 &&
      (std::memcmp(magic, "II*\0", 4) == 0 || std::memcmp(magic, "MM\0*", 4) == 0)) {
    f.clear();
    f.seekg(4);
    return tiff_header(f, path, magic[0] == 'I');
  }
  return {};
}

}  // namespace sonar3d::detail
