#pragma once
// Little-endian loads and stores for the binary log formats (ARIS, CDR, ROS 1 bags). Internal to
// src/io: every read is bounds-checked by the caller against the buffer it came from.
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace sonar3d::bin {

template <class T>
inline T load(const unsigned char* p) {
  T v;
  std::memcpy(&v, p, sizeof v);  // the formats are little-endian, as every machine we build for
  return v;
}
template <class T>
inline void store(unsigned char* p, T v) {
  std::memcpy(p, &v, sizeof v);
}
template <class T>
inline void append(std::vector<unsigned char>& out, T v) {
  const std::size_t at = out.size();
  out.resize(at + sizeof v);
  std::memcpy(out.data() + at, &v, sizeof v);
}
inline void append_bytes(std::vector<unsigned char>& out, const void* p, std::size_t n) {
  const auto* b = static_cast<const unsigned char*>(p);
  out.insert(out.end(), b, b + n);
}

inline std::string hex32(std::uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%08x", v);
  return buf;
}

}  // namespace sonar3d::bin
