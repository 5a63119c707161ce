// NumPy .npy/.npz reading by hand, bounded by the file's size (include/sonar3d/video/npz.hpp).
#include "sonar3d/video/npz.hpp"

#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <fstream>

#include "sonar3d/core/error.hpp"

namespace sonar3d {

namespace {

constexpr std::size_t kMaxEntryBytes = 64u << 20;  // one array, uncompressed
constexpr std::size_t kMaxFileBytes = 1u << 30;
constexpr std::size_t kMaxDims = 32;  // NumPy's own limit (NPY_MAXDIMS)

std::uint32_t le16(const std::uint8_t* p) { return p[0] | (p[1] << 8); }
std::uint32_t le32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
         (static_cast<std::uint32_t>(p[2]) << 16) | (static_cast<std::uint32_t>(p[3]) << 24);
}

// The header of a .npy: a Python dict literal such as
//   {'descr': '<f8', 'fortran_order': False, 'shape': (3, 4), }
struct DictParser {
  const std::string& s;
  const std::string& where;
  std::size_t i = 0;
  [[noreturn]] void fail(const std::string& what) const {
    throw Error(where + ": bad .npy header (" + what + "): '" + printable(s, 120) + "'");
  }
  void ws() {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\n' || s[i] == '\t')) ++i;
  }
  bool eat(char c) {
    ws();
    if (i < s.size() && s[i] == c) {
      ++i;
      return true;
    }
    return false;
  }
  std::string quoted() {
    ws();
    if (i >= s.size() || (s[i] != '\'' && s[i] != '"')) fail("expected a quoted string");
    const char q = s[i++];
    const std::size_t end = s.find(q, i);
    if (end == std::string::npos) fail("unterminated string");
    std::string out = s.substr(i, end - i);
    i = end + 1;
    return out;
  }
  std::string word() {
    ws();
    const std::size_t b = i;
    while (i < s.size() && std::isalpha(static_cast<unsigned char>(s[i]))) ++i;
    return s.substr(b, i - b);
  }
  std::vector<std::size_t> tuple() {
    if (!eat('(')) fail("shape is not a tuple");
    std::vector<std::size_t> dims;
    while (!eat(')')) {
      ws();
      std::size_t v = 0, digits = 0;
      while (i < s.size() && s[i] >= '0' && s[i] <= '9') {
        if (++digits > 12) fail("a dimension of more than 12 digits");
        v = v * 10 + static_cast<std::size_t>(s[i++] - '0');
      }
      if (digits == 0) fail("a dimension is not a whole number");
      dims.push_back(v);
      if (dims.size() > kMaxDims) fail("more than 32 dimensions");
      if (!eat(',')) {
        if (!eat(')')) fail("expected ',' or ')' in the shape");
        break;
      }
    }
    return dims;
  }
};

}  // namespace

NpyArray parse_npy(const std::uint8_t* b, std::size_t size, const std::string& where) {
  static const std::uint8_t kMagic[6] = {0x93, 'N', 'U', 'M', 'P', 'Y'};
  if (size < 10 || std::memcmp(b, kMagic, 6) != 0) {
    throw Error(where + ": not a .npy array (no \\x93NUMPY magic)");
  }
  const int major = b[6];
  std::size_t header_len = 0, at = 0;
  if (major == 1) {
    header_len = le16(b + 8);
    at = 10;
  } else if (major == 2 || major == 3) {
    if (size < 12) throw Error(where + ": truncated .npy header");
    header_len = le32(b + 8);
    at = 12;
  } else {
    throw Error(where + ": .npy format version " + std::to_string(major) + " (1, 2 or 3 read)");
  }
  if (header_len > size - at) {
    throw Error(where + ": the .npy header declares " + std::to_string(header_len) +
                " bytes but the array holds " + std::to_string(size - at));
  }
  const std::string header(reinterpret_cast<const char*>(b + at), header_len);
  at += header_len;
  DictParser p{header, where};
  if (!p.eat('{')) p.fail("not a dict");
  std::string descr;
  bool fortran = false, have_descr = false, have_order = false, have_shape = false;
  std::vector<std::size_t> shape;
  while (!p.eat('}')) {
    const std::string key = p.quoted();
    if (!p.eat(':')) p.fail("expected ':'");
    if (key == "descr") {
      descr = p.quoted();
      have_descr = true;
    } else if (key == "fortran_order") {
      const std::string w = p.word();
      if (w != "True" && w != "False") p.fail("fortran_order is neither True nor False");
      fortran = w == "True";
      have_order = true;
    } else if (key == "shape") {
      shape = p.tuple();
      have_shape = true;
    } else {
      p.fail("unknown key '" + key + "'");
    }
    if (!p.eat(',')) {
      if (!p.eat('}')) p.fail("expected ',' or '}'");
      break;
    }
  }
  if (!have_descr || !have_order || !have_shape) p.fail("descr, fortran_order or shape missing");
  std::size_t item = 0;
  if (descr == "<f8" || descr == "f8" || descr == "<d") {
    item = 8;
  } else if (descr == "<f4" || descr == "f4" || descr == "<f") {
    item = 4;
  } else {
    throw Error(where + ": dtype '" + printable(descr) +
                "' is not supported (little-endian float64 '<f8' or float32 '<f4')");
  }
  if (fortran) {
    throw Error(where + ": the array is in Fortran order (C order expected; np.ascontiguousarray)");
  }
  // The element count, bounded by the bytes that follow (no overflow: each step is checked).
  const std::size_t data = size - at;
  std::size_t count = 1;
  for (std::size_t d : shape) {
    if (d != 0 && count > data / item / d) {
      throw Error(where + ": shape declares more values than the " + std::to_string(data) +
                  " bytes of data hold");
    }
    count *= d;
  }
  if (count * item != data) {
    throw Error(where + ": " + std::to_string(data) + " bytes of data for " +
                std::to_string(count) + " values of " + std::to_string(item) + " bytes");
  }
  NpyArray a;
  a.shape = shape;
  a.data.resize(count);
  for (std::size_t k = 0; k < count; ++k) {
    if (item == 8) {
      double v;
      std::memcpy(&v, b + at + 8 * k, 8);
      a.data[k] = v;
    } else {
      float v;
      std::memcpy(&v, b + at + 4 * k, 4);
      a.data[k] = v;
    }
  }
  return a;
}

namespace {

std::vector<std::uint8_t> slurp(const std::filesystem::path& path) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) throw Error("cannot read '" + path.string() + "': " + ec.message());
  if (size > kMaxFileBytes) {
    throw Error("'" + path.string() + "' is larger than 1 GiB: not a camera file");
  }
  std::ifstream f(path, std::ios::binary);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
  if (!f || !f.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(size))) {
    throw Error("cannot read '" + path.string() + "'");
  }
  return bytes;
}

}  // namespace

NpyArray read_npy(const std::filesystem::path& path) {
  const auto bytes = slurp(path);
  return parse_npy(bytes.data(), bytes.size(), path.string());
}

std::map<std::string, NpyArray> parse_npz(const std::uint8_t* b, std::size_t size,
                                          const std::string& where) {
  // The end of central directory record: 22 bytes plus a comment of up to 65535, at the end.
  if (size < 22) throw Error(where + ": not a .npz (too short for a zip)");
  std::size_t eocd = std::string::npos;
  const std::size_t lowest = size > 22 + 65535 ? size - 22 - 65535 : 0;
  for (std::size_t k = size - 22 + 1; k-- > lowest;) {
    if (le32(b + k) == 0x06054b50 && k + 22 + le16(b + k + 20) == size) {
      eocd = k;
      break;
    }
  }
  if (eocd == std::string::npos) throw Error(where + ": not a .npz (no zip directory at its end)");
  const std::size_t entries = le16(b + eocd + 10);
  const std::size_t cd_size = le32(b + eocd + 12), cd_offset = le32(b + eocd + 16);
  if (le16(b + eocd + 4) != 0 || le16(b + eocd + 6) != 0 || le16(b + eocd + 8) != entries) {
    throw Error(where + ": multi-part zip archives are not supported");
  }
  if (cd_offset == 0xffffffffu || entries == 0xffff) {
    throw Error(where + ": zip64 archives are not supported (arrays this large are no cameras)");
  }
  if (cd_offset > eocd || cd_size > eocd - cd_offset) {
    throw Error(where + ": the zip directory lies outside the file");
  }
  std::map<std::string, NpyArray> out;
  std::size_t at = cd_offset;
  for (std::size_t e = 0; e < entries; ++e) {
    if (at + 46 > cd_offset + cd_size || le32(b + at) != 0x02014b50) {
      throw Error(where + ": zip directory entry " + std::to_string(e) + " is corrupt");
    }
    const std::uint32_t flags = le16(b + at + 8), method = le16(b + at + 10);
    const std::uint32_t crc = le32(b + at + 16);
    const std::size_t csize = le32(b + at + 20), usize = le32(b + at + 24);
    const std::size_t name_len = le16(b + at + 28), extra_len = le16(b + at + 30),
                      comment_len = le16(b + at + 32);
    const std::size_t local = le32(b + at + 42);
    if (at + 46 + name_len + extra_len + comment_len > cd_offset + cd_size) {
      throw Error(where + ": zip directory entry " + std::to_string(e) + " is corrupt");
    }
    std::string name(reinterpret_cast<const char*>(b + at + 46), name_len);
    at += 46 + name_len + extra_len + comment_len;
    const std::string ewhere = where + ": " + printable(name, 80);
    if (flags & 1) throw Error(ewhere + " is encrypted");
    if (csize == 0xffffffffu || usize == 0xffffffffu || local == 0xffffffffu) {
      throw Error(ewhere + ": zip64 entries are not supported");
    }
    if (method != 0 && method != 8) {
      throw Error(ewhere + ": compression method " + std::to_string(method) +
                  " (stored or deflated read)");
    }
    if (usize > kMaxEntryBytes) throw Error(ewhere + " declares more than 64 MiB");
    // Deflate cannot expand more than ~1032:1: a larger declared size is a lie.
    if ((method == 0 && usize != csize) || (method == 8 && usize > 1032 * csize + 64)) {
      throw Error(ewhere + ": declared sizes are inconsistent (" + std::to_string(csize) +
                  " compressed, " + std::to_string(usize) + " uncompressed)");
    }
    if (local > cd_offset || cd_offset - local < 30 || le32(b + local) != 0x04034b50) {
      throw Error(ewhere + ": its local header is missing or corrupt");
    }
    const std::size_t data = local + 30 + le16(b + local + 26) + le16(b + local + 28);
    if (data > cd_offset || csize > cd_offset - data) {
      throw Error(ewhere + ": its data runs past the zip directory");
    }
    std::vector<std::uint8_t> raw(usize);
    if (method == 0) {
      std::copy(b + data, b + data + csize, raw.begin());
    } else {
      z_stream z{};
      if (inflateInit2(&z, -MAX_WBITS) != Z_OK) throw Error(ewhere + ": zlib failed to start");
      z.next_in = const_cast<Bytef*>(b + data);
      z.avail_in = static_cast<uInt>(csize);
      z.next_out = raw.data();
      z.avail_out = static_cast<uInt>(usize);
      const int rc = inflate(&z, Z_FINISH);
      const std::size_t produced = usize - z.avail_out;
      inflateEnd(&z);
      if (rc != Z_STREAM_END || produced != usize) {
        throw Error(ewhere + ": corrupt deflate data (or larger than its declared " +
                    std::to_string(usize) + " bytes)");
      }
    }
    const uLong got = crc32(crc32(0L, Z_NULL, 0), raw.data(), static_cast<uInt>(raw.size()));
    if (got != crc) throw Error(ewhere + ": CRC mismatch (the file is corrupt)");
    if (name.size() < 4 || name.compare(name.size() - 4, 4, ".npy") != 0) {
      throw Error(ewhere + " is not a .npy array");
    }
    name.resize(name.size() - 4);
    if (out.count(name)) throw Error(ewhere + " appears twice");
    out.emplace(name, parse_npy(raw.data(), raw.size(), ewhere));
  }
  return out;
}

std::map<std::string, NpyArray> read_npz(const std::filesystem::path& path) {
  const auto bytes = slurp(path);
  return parse_npz(bytes.data(), bytes.size(), path.string());
}

}  // namespace sonar3d
