#include "sonar3d/core/point_cloud.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"

namespace sonar3d {
namespace {

struct PlyProperty {
  std::string name;
  std::string type;
  int size = 0;
};

int ply_type_size(const std::string& t) {
  if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
  if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
  if (t == "int" || t == "uint" || t == "float" || t == "int32" || t == "uint32" || t == "float32")
    return 4;
  if (t == "double" || t == "float64") return 8;
  return 0;
}

// A PLY scalar type as a code, resolved once per property (comparing the type's name for every
// value made reading a 4 M-point cloud several times slower).
enum class PlyType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };
PlyType ply_type(const std::string& t) {
  if (t == "char" || t == "int8") return PlyType::Int8;
  if (t == "uchar" || t == "uint8") return PlyType::UInt8;
  if (t == "short" || t == "int16") return PlyType::Int16;
  if (t == "ushort" || t == "uint16") return PlyType::UInt16;
  if (t == "int" || t == "int32") return PlyType::Int32;
  if (t == "uint" || t == "uint32") return PlyType::UInt32;
  if (t == "float" || t == "float32") return PlyType::Float32;
  return PlyType::Float64;
}

double read_binary_value(const char* p, PlyType t, bool big_endian = false) {
  auto get = [p, big_endian](auto v) {
    char b[sizeof(v)];
    std::memcpy(b, p, sizeof(v));
    if (big_endian) std::reverse(b, b + sizeof(v));  // hosts are little-endian (x86, arm)
    std::memcpy(&v, b, sizeof(v));
    return static_cast<double>(v);
  };
  switch (t) {
    case PlyType::Int8:
      return get(int8_t{});
    case PlyType::UInt8:
      return get(uint8_t{});
    case PlyType::Int16:
      return get(int16_t{});
    case PlyType::UInt16:
      return get(uint16_t{});
    case PlyType::Int32:
      return get(int32_t{});
    case PlyType::UInt32:
      return get(uint32_t{});
    case PlyType::Float32:
      return get(float{});
    case PlyType::Float64:
      break;
  }
  return get(double{});
}
double read_binary_value(const char* p, const std::string& t, bool big_endian = false) {
  return read_binary_value(p, ply_type(t), big_endian);
}

}  // namespace

namespace {

// A PLY element of the header: its count and properties (a list property has a count type).
struct PlyElement {
  std::string name;
  unsigned long long count = 0;
  std::vector<PlyProperty> props;
  std::vector<std::string> list_count_type;  // per property: "" for a scalar
  int line = 0;
};

// A decimal count: digits only (no sign, exponent, "inf" or "1e309"), at most 18 of them.
bool parse_count(const std::string& s, unsigned long long* out) {
  if (s.empty() || s.size() > 18) return false;
  unsigned long long v = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + static_cast<unsigned>(c - '0');
  }
  *out = v;
  return true;
}

// A finite decimal number filling the whole token.
bool parse_ascii_value(const std::string& tok, double* out) {
  if (tok.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(tok.c_str(), &end);
  if (end != tok.c_str() + tok.size() || errno == ERANGE || !std::isfinite(v)) return false;
  *out = v;
  return true;
}

}  // namespace

PointCloud read_ply(const std::string& path) { return read_ply_faces(path, nullptr); }

PointCloud read_ply_faces(const std::string& path, std::vector<std::vector<uint32_t>>* faces) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error("cannot open point cloud '" + path + "'");
  std::error_code ec;
  const auto file_size = static_cast<unsigned long long>(std::filesystem::file_size(path, ec));
  if (ec) throw Error("cannot read the size of point cloud '" + path + "'");
  std::string line;
  int lineno = 0;
  auto fail = [&](const std::string& msg) {
    throw Error(path + ":" + std::to_string(lineno) + ": " + msg);
  };
  // Header lines are short; a header is read with a bound so that a file without newlines is not
  // pulled into memory as one line.
  constexpr std::size_t kMaxHeaderLine = 4096;
  constexpr int kMaxHeaderLines = 4096;
  auto next_line = [&]() -> bool {
    line.clear();
    char c;
    while (f.get(c)) {
      if (c == '\n') break;
      if (line.size() >= kMaxHeaderLine) {
        ++lineno;
        fail("header line longer than " + std::to_string(kMaxHeaderLine) + " bytes");
      }
      line.push_back(c);
    }
    if (!f && line.empty()) return false;
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (lineno > kMaxHeaderLines) {
      fail("header longer than " + std::to_string(kMaxHeaderLines) + " lines");
    }
    return true;
  };
  if (!next_line() || line != "ply") fail("not a PLY file (missing 'ply' magic)");
  std::string format;
  std::vector<PlyElement> elements;
  bool ended = false;
  while (next_line()) {
    std::istringstream is(line);
    std::vector<std::string> tok;
    for (std::string t; is >> t;) tok.push_back(t);
    if (tok.empty()) fail("empty header line");
    const std::string& key = tok[0];
    if (key == "comment" || key == "obj_info") continue;
    if (key == "format") {
      if (!format.empty()) fail("a second 'format' line");
      if (tok.size() != 3 || tok[2] != "1.0") fail("expected 'format <type> 1.0'");
      format = tok[1];
      if (format != "ascii" && format != "binary_little_endian" && format != "binary_big_endian") {
        fail("unsupported PLY format '" + printable(format) +
             "' (ascii, binary_little_endian or binary_big_endian)");
      }
    } else if (key == "element") {
      if (tok.size() != 3) fail("expected 'element <name> <count>'");
      PlyElement e;
      e.name = tok[1];
      e.line = lineno;
      if (!parse_count(tok[2], &e.count)) {
        fail("element '" + e.name + "' count '" + printable(tok[2]) +
             "' is not a whole number of at most 18 digits");
      }
      for (const auto& other : elements) {
        if (other.name == e.name) fail("element '" + e.name + "' declared twice");
      }
      if (elements.empty() && e.name != "vertex") {
        fail("elements before 'vertex' are not supported");
      }
      elements.push_back(e);
    } else if (key == "property") {
      if (elements.empty()) fail("'property' before any 'element'");
      PlyElement& e = elements.back();
      std::string list_type;
      PlyProperty prop;
      if (tok.size() == 5 && tok[1] == "list") {
        if (e.name == "vertex") fail("list properties on vertices are not supported");
        list_type = tok[2];
        const int cs = ply_type_size(list_type);
        if (cs == 0 || list_type.find("float") != std::string::npos || list_type == "double") {
          fail("list count type '" + list_type + "' must be an integer type");
        }
        prop = {tok[4], tok[3], ply_type_size(tok[3])};
      } else if (tok.size() == 3) {
        prop = {tok[2], tok[1], ply_type_size(tok[1])};
      } else {
        fail("expected 'property <type> <name>' or 'property list <type> <type> <name>'");
      }
      if (prop.size == 0) fail("unknown property type '" + printable(prop.type) + "'");
      for (const auto& other : e.props) {
        if (other.name == prop.name) fail("property '" + prop.name + "' declared twice");
      }
      e.props.push_back(prop);
      e.list_count_type.push_back(list_type);
    } else if (key == "end_header") {
      if (tok.size() != 1) fail("unexpected text after 'end_header'");
      ended = true;
      break;
    } else {
      fail("unknown header keyword '" + printable(key) + "'");
    }
  }
  if (!ended) fail("the header has no 'end_header' line");
  if (format.empty()) fail("missing 'format' line");
  if (elements.empty()) fail("missing 'element vertex'");
  const PlyElement& vert = elements.front();
  const auto& props = vert.props;
  int ix = -1, iy = -1, iz = -1, ii = -1, ir = -1, ig = -1, ib = -1;
  for (int k = 0; k < static_cast<int>(props.size()); ++k) {
    const auto& n = props[k].name;
    if (n == "x") ix = k;
    if (n == "y") iy = k;
    if (n == "z") iz = k;
    if (n == "intensity" || n == "scalar_intensity" || n == "scalar_Intensity") ii = k;
    if (n == "red" || n == "diffuse_red") ir = k;
    if (n == "green" || n == "diffuse_green") ig = k;
    if (n == "blue" || n == "diffuse_blue") ib = k;
  }
  if (ix < 0 || iy < 0 || iz < 0) fail("vertex has no x, y, z properties");
  // A colour only from all three as 8-bit (what PLY tools write); other types (16-bit, float
  // 0 … 1) are skipped like any extra property, as before colours were read.
  auto is_u8 = [&](int k) { return props[k].type == "uchar" || props[k].type == "uint8"; };
  const bool has_color = ir >= 0 && ig >= 0 && ib >= 0 && is_u8(ir) && is_u8(ig) && is_u8(ib);
  const unsigned long long vertex_count = vert.count;
  const unsigned long long data_bytes = file_size - static_cast<unsigned long long>(f.tellg());
  // Sizes are checked against the file before anything is allocated: a binary vertex takes
  // `stride` bytes and an ascii one at least two per value ("0 ").
  unsigned long long stride = 0;
  for (const auto& p : props) stride += static_cast<unsigned long long>(p.size);
  const unsigned long long min_bytes = format == "ascii" ? 2 * props.size() : stride;
  if (vertex_count > data_bytes / min_bytes) {
    lineno = vert.line;
    fail("declares " + std::to_string(vertex_count) + " vertices but only " +
         std::to_string(data_bytes) + " bytes of data follow the header (" +
         (format == "ascii" ? "at least " : "") + std::to_string(min_bytes) +
         " bytes per vertex): the file is truncated or its header is wrong");
  }
  const bool big = format == "binary_big_endian";
  if (faces) faces->clear();
  auto is_face_list = [](const PlyElement& e, std::size_t k) {
    return e.name == "face" && !e.list_count_type[k].empty() &&
           (e.props[k].name == "vertex_indices" || e.props[k].name == "vertex_index");
  };
  auto face_index = [&](double x, unsigned long long face) -> uint32_t {
    if (!(x >= 0) || x != std::floor(x) || x >= static_cast<double>(vertex_count)) {
      std::ostringstream os;
      os << path << ": face " << face << " refers to vertex " << x << " of " << vertex_count;
      throw Error(os.str());
    }
    return static_cast<uint32_t>(x);
  };
  PointCloud cloud;
  cloud.points.resize(vertex_count);
  if (ii >= 0) cloud.intensity.resize(vertex_count);
  if (has_color) cloud.color.resize(vertex_count);
  // Point clouds (not meshes) keep their other vertex scalars as named properties (the uchar
  // colour, when read as one, is not among them).
  std::vector<int> extra;
  if (!faces) {
    for (int k = 0; k < static_cast<int>(props.size()); ++k) {
      if (k == ix || k == iy || k == iz || k == ii) continue;
      if (has_color && (k == ir || k == ig || k == ib)) continue;
      extra.push_back(k);
      cloud.properties.push_back({props[k].name, std::vector<float>(vertex_count)});
    }
  }
  std::vector<double> vals(props.size());
  auto store = [&](unsigned long long v) {
    for (std::size_t k = 0; k < vals.size(); ++k) {
      if (!std::isfinite(vals[k])) {
        throw Error(path + ": vertex " + std::to_string(v) + " property '" + props[k].name +
                    "' is not finite");
      }
    }
    cloud.points[v] = Eigen::Vector3f(vals[ix], vals[iy], vals[iz]);
    if (!cloud.points[v].allFinite()) {
      throw Error(path + ": vertex " + std::to_string(v) + " has a coordinate beyond float range");
    }
    if (ii >= 0) cloud.intensity[v] = static_cast<float>(vals[ii]);
    if (has_color) {
      const int idx[3] = {ir, ig, ib};
      for (int c = 0; c < 3; ++c) {
        cloud.color[v][c] = static_cast<std::uint8_t>(std::lround(vals[idx[c]]));
      }
    }
    for (std::size_t e = 0; e < extra.size(); ++e) {
      cloud.properties[e].values[v] = static_cast<float>(vals[extra[e]]);
    }
  };
  if (format == "ascii") {
    // One line per element item; every line holds exactly its properties' values.
    for (const PlyElement& e : elements) {
      for (unsigned long long v = 0; v < e.count; ++v) {
        if (!std::getline(f, line)) {
          throw Error(path + ": file ends at " + e.name + " " + std::to_string(v) + " of " +
                      std::to_string(e.count));
        }
        ++lineno;
        std::istringstream is(line);
        std::vector<std::string> tok;
        for (std::string t; is >> t;) tok.push_back(t);
        std::size_t at = 0;
        for (std::size_t k = 0; k < e.props.size(); ++k) {
          unsigned long long n = 1;
          if (!e.list_count_type[k].empty()) {
            if (at >= tok.size() || !parse_count(tok[at], &n)) {
              fail(e.name + " " + std::to_string(v) + ": bad list length");
            }
            ++at;
          }
          const bool face_list = faces && is_face_list(e, k);
          if (face_list) faces->emplace_back();
          for (unsigned long long c = 0; c < n; ++c, ++at) {
            double x = 0;
            if (at >= tok.size()) fail(e.name + " " + std::to_string(v) + " has too few values");
            if (!parse_ascii_value(tok[at], &x)) {
              fail(e.name + " " + std::to_string(v) + ": '" + printable(tok[at], 40) +
                   "' is not a finite number");
            }
            if (&e == &vert) vals[k] = x;
            if (face_list) faces->back().push_back(face_index(x, v));
          }
        }
        if (at != tok.size()) fail(e.name + " " + std::to_string(v) + " has too many values");
        if (&e == &vert) store(v);
      }
    }
    while (std::getline(f, line)) {
      ++lineno;
      if (line.find_first_not_of(" \t\r") != std::string::npos) {
        fail("unexpected data after the last element");
      }
    }
  } else {
    std::vector<char> buf(static_cast<std::size_t>(stride * vertex_count));
    f.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    std::vector<PlyType> types;
    for (const auto& pr : props) types.push_back(ply_type(pr.type));
    for (unsigned long long v = 0; v < vertex_count; ++v) {
      const char* p = buf.data() + static_cast<std::size_t>(v * stride);
      for (std::size_t k = 0; k < props.size(); ++k) {
        vals[k] = read_binary_value(p, types[k], big);
        p += props[k].size;
      }
      store(v);
    }
    // The other elements (faces ...) are walked to find where the file must end, so a retyped
    // property or a wrong count shows as a size mismatch instead of being read as shifted data.
    unsigned long long pos = static_cast<unsigned long long>(f.tellg());
    for (std::size_t ei = 1; ei < elements.size(); ++ei) {
      const PlyElement& e = elements[ei];
      unsigned long long item_min = 0;  // bytes per item at least (an empty list has its count)
      for (std::size_t k = 0; k < e.props.size(); ++k) {
        item_min += static_cast<unsigned long long>(
            e.list_count_type[k].empty() ? e.props[k].size : ply_type_size(e.list_count_type[k]));
      }
      if (e.count > 0 && (item_min == 0 || e.count > (file_size - pos) / item_min)) {
        lineno = e.line;
        fail("element '" + e.name + "' declares " + std::to_string(e.count) +
             " items, more than the rest of the file can hold");
      }
      for (unsigned long long v = 0; v < e.count; ++v) {
        for (std::size_t k = 0; k < e.props.size(); ++k) {
          unsigned long long n = 1;
          if (!e.list_count_type[k].empty()) {
            const int cs = ply_type_size(e.list_count_type[k]);
            char b[8] = {};
            if (!f.read(b, cs)) {
              throw Error(path + ": truncated binary PLY in element '" + e.name + "' " +
                          std::to_string(v));
            }
            const double d = read_binary_value(b, e.list_count_type[k], big);
            if (d < 0) {
              throw Error(path + ": element '" + e.name + "' " + std::to_string(v) +
                          " has a negative list length");
            }
            n = static_cast<unsigned long long>(d);
            pos += static_cast<unsigned long long>(cs);
          }
          const unsigned long long bytes = n * static_cast<unsigned long long>(e.props[k].size);
          if (n > file_size || pos + bytes > file_size) {
            throw Error(path + ": truncated binary PLY in element '" + e.name + "' " +
                        std::to_string(v));
          }
          if (faces && is_face_list(e, k)) {
            std::vector<char> b(static_cast<std::size_t>(bytes));
            f.read(b.data(), static_cast<std::streamsize>(bytes));
            faces->emplace_back();
            for (unsigned long long c = 0; c < n; ++c) {
              faces->back().push_back(face_index(
                  read_binary_value(b.data() + c * e.props[k].size, e.props[k].type, big), v));
            }
          } else {
            // Skipped within the stream's buffer: a seekg() per item (a syscall pair each) took
            // 8 s for a 1.6 M-face seabed mesh.
            f.ignore(static_cast<std::streamsize>(bytes));
          }
          pos += bytes;
        }
      }
    }
    if (pos != file_size) {
      throw Error(path + ": " + std::to_string(file_size - pos) +
                  " bytes of unexpected data after the last element (is the header's property "
                  "list or count right?)");
    }
  }
  return cloud;
}

void write_ply(const std::string& path, const PointCloud& cloud, PlyFormat format) {
  if (cloud.has_intensity() && cloud.intensity.size() != cloud.points.size()) {
    throw Error("cannot write '" + path + "': intensity count differs from point count");
  }
  if (cloud.has_color() && cloud.color.size() != cloud.points.size()) {
    throw Error("cannot write '" + path + "': colour count differs from point count");
  }
  for (const auto& p : cloud.properties) {
    const bool name_ok = !p.name.empty() && p.name.find_first_of(" \t\r\n") == std::string::npos;
    if (!name_ok || p.values.size() != cloud.points.size()) {
      throw Error("cannot write '" + path + "': property '" + printable(p.name) +
                  "' has no valid name or not one value per point");
    }
    if (cloud.has_color() && (p.name == "red" || p.name == "green" || p.name == "blue")) {
      throw Error("cannot write '" + path + "': property '" + p.name + "' clashes with the colour");
    }
  }
  AtomicPath out(path);
  {
    std::ofstream f(out.temp(), std::ios::binary);
    if (!f) throw Error("cannot open '" + path + "' for writing");
    f << "ply\nformat " << (format == PlyFormat::Binary ? "binary_little_endian" : "ascii")
      << " 1.0\ncomment sonar3d point cloud, world frame, metres\nelement vertex " << cloud.size()
      << "\nproperty float x\nproperty float y\nproperty float z\n";
    if (cloud.has_intensity()) f << "property float intensity\n";
    if (cloud.has_color()) f << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    for (const auto& p : cloud.properties) f << "property float " << p.name << "\n";
    f << "end_header\n";
    if (format == PlyFormat::Binary) {
      std::vector<char> rec;
      const std::size_t stride = 12 + (cloud.has_intensity() ? 4 : 0) +
                                 (cloud.has_color() ? 3 : 0) + 4 * cloud.properties.size();
      rec.resize(cloud.size() * stride);
      char* p = rec.data();
      for (std::size_t i = 0; i < cloud.size(); ++i) {
        std::memcpy(p, cloud.points[i].data(), 12);
        p += 12;
        if (cloud.has_intensity()) {
          std::memcpy(p, &cloud.intensity[i], 4);
          p += 4;
        }
        if (cloud.has_color()) {
          std::memcpy(p, cloud.color[i].data(), 3);
          p += 3;
        }
        for (const auto& pr : cloud.properties) {
          std::memcpy(p, &pr.values[i], 4);
          p += 4;
        }
      }
      f.write(rec.data(), static_cast<std::streamsize>(rec.size()));
    } else {
      f.precision(9);
      for (std::size_t i = 0; i < cloud.size(); ++i) {
        const auto& p = cloud.points[i];
        f << p.x() << ' ' << p.y() << ' ' << p.z();
        if (cloud.has_intensity()) f << ' ' << cloud.intensity[i];
        if (cloud.has_color()) {
          f << ' ' << int(cloud.color[i][0]) << ' ' << int(cloud.color[i][1]) << ' '
            << int(cloud.color[i][2]);
        }
        for (const auto& pr : cloud.properties) f << ' ' << pr.values[i];
        f << '\n';
      }
    }
    f.close();
    if (!f) throw Error("failed writing '" + path + "' (disk full?)");
  }
  out.commit();
}

bool is_sonar3d_ply(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return false;
  // write_ply's first three lines: "ply", the format, the comment.
  char head[256] = {};
  f.read(head, sizeof(head) - 1);
  const std::string h(head, static_cast<std::size_t>(f.gcount()));
  return h.rfind("ply\nformat ", 0) == 0 &&
         (h.find("\ncomment sonar3d point cloud, world frame, metres\n") != std::string::npos ||
          h.find("\ncomment sonar3d textured mesh, world frame, metres") != std::string::npos);
}

}  // namespace sonar3d
