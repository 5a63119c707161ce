#include "sonar3d/core/point_cloud.hpp"

#include <cmath>
#include <cstring>
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
  if (t == "int" || t == "uint" || t == "float" || t == "int32" || t == "uint32" ||
      t == "float32")
    return 4;
  if (t == "double" || t == "float64") return 8;
  return 0;
}

double read_binary_value(const char* p, const std::string& t) {
  auto get = [p](auto v) {
    std::memcpy(&v, p, sizeof(v));
    return static_cast<double>(v);
  };
  if (t == "char" || t == "int8") return get(int8_t{});
  if (t == "uchar" || t == "uint8") return get(uint8_t{});
  if (t == "short" || t == "int16") return get(int16_t{});
  if (t == "ushort" || t == "uint16") return get(uint16_t{});
  if (t == "int" || t == "int32") return get(int32_t{});
  if (t == "uint" || t == "uint32") return get(uint32_t{});
  if (t == "float" || t == "float32") return get(float{});
  return get(double{});
}

}  // namespace

PointCloud read_ply(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error("cannot open point cloud '" + path + "'");
  std::string line;
  int lineno = 0;
  auto fail = [&](const std::string& msg) {
    throw Error(path + ":" + std::to_string(lineno) + ": " + msg);
  };
  std::getline(f, line);
  ++lineno;
  if (line.rfind("ply", 0) != 0) fail("not a PLY file (missing 'ply' magic)");
  std::string format;
  long long vertex_count = -1;
  bool in_vertex = false;
  bool vertex_seen = false;
  std::vector<PlyProperty> props;
  while (std::getline(f, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream is(line);
    std::string key;
    is >> key;
    if (key == "format") {
      is >> format;
      if (format != "ascii" && format != "binary_little_endian") {
        fail("unsupported PLY format '" + format + "' (ascii or binary_little_endian)");
      }
    } else if (key == "element") {
      std::string name;
      long long n = -1;
      is >> name >> n;
      in_vertex = (name == "vertex");
      if (in_vertex) {
        if (n < 0) fail("bad vertex count");
        vertex_count = n;
        vertex_seen = true;
      } else if (!vertex_seen) {
        fail("elements before 'vertex' are not supported");
      }
    } else if (key == "property") {
      if (!in_vertex) continue;
      std::string type, name;
      is >> type;
      if (type == "list") fail("list properties on vertices are not supported");
      is >> name;
      const int size = ply_type_size(type);
      if (size == 0) fail("unknown property type '" + type + "'");
      props.push_back({name, type, size});
    } else if (key == "end_header") {
      break;
    }
  }
  if (format.empty()) fail("missing 'format' line");
  if (vertex_count < 0) fail("missing 'element vertex'");
  int ix = -1, iy = -1, iz = -1, ii = -1;
  for (int k = 0; k < static_cast<int>(props.size()); ++k) {
    const auto& n = props[k].name;
    if (n == "x") ix = k;
    if (n == "y") iy = k;
    if (n == "z") iz = k;
    if (n == "intensity" || n == "scalar_intensity" || n == "scalar_Intensity") ii = k;
  }
  if (ix < 0 || iy < 0 || iz < 0) fail("vertex has no x, y, z properties");
  PointCloud cloud;
  cloud.points.resize(vertex_count);
  if (ii >= 0) cloud.intensity.resize(vertex_count);
  std::vector<double> vals(props.size());
  if (format == "ascii") {
    for (long long v = 0; v < vertex_count; ++v) {
      if (!std::getline(f, line)) fail("file ends at vertex " + std::to_string(v));
      ++lineno;
      std::istringstream is(line);
      for (auto& x : vals) {
        if (!(is >> x)) fail("vertex " + std::to_string(v) + " has too few values");
      }
      cloud.points[v] = Eigen::Vector3f(vals[ix], vals[iy], vals[iz]);
      if (ii >= 0) cloud.intensity[v] = static_cast<float>(vals[ii]);
    }
  } else {
    int stride = 0;
    for (const auto& p : props) stride += p.size;
    std::vector<char> buf(static_cast<std::size_t>(stride) * vertex_count);
    f.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    if (f.gcount() != static_cast<std::streamsize>(buf.size())) {
      throw Error(path + ": truncated binary PLY: expected " + std::to_string(vertex_count) +
                  " vertices of " + std::to_string(stride) + " bytes");
    }
    for (long long v = 0; v < vertex_count; ++v) {
      const char* p = buf.data() + static_cast<std::size_t>(v) * stride;
      for (std::size_t k = 0; k < props.size(); ++k) {
        vals[k] = read_binary_value(p, props[k].type);
        p += props[k].size;
      }
      cloud.points[v] = Eigen::Vector3f(vals[ix], vals[iy], vals[iz]);
      if (ii >= 0) cloud.intensity[v] = static_cast<float>(vals[ii]);
    }
  }
  for (std::size_t v = 0; v < cloud.points.size(); ++v) {
    if (!cloud.points[v].allFinite()) {
      throw Error(path + ": vertex " + std::to_string(v) + " has a non-finite coordinate");
    }
  }
  return cloud;
}

void write_ply(const std::string& path, const PointCloud& cloud, PlyFormat format) {
  if (cloud.has_intensity() && cloud.intensity.size() != cloud.points.size()) {
    throw Error("cannot write '" + path + "': intensity count differs from point count");
  }
  AtomicPath out(path);
  {
    std::ofstream f(out.temp(), std::ios::binary);
    if (!f) throw Error("cannot open '" + path + "' for writing");
    f << "ply\nformat " << (format == PlyFormat::Binary ? "binary_little_endian" : "ascii")
      << " 1.0\ncomment sonar3d point cloud, world frame, metres\nelement vertex "
      << cloud.size() << "\nproperty float x\nproperty float y\nproperty float z\n";
    if (cloud.has_intensity()) f << "property float intensity\n";
    f << "end_header\n";
    if (format == PlyFormat::Binary) {
      std::vector<float> rec;
      rec.reserve(cloud.size() * 4);
      for (std::size_t i = 0; i < cloud.size(); ++i) {
        rec.insert(rec.end(), cloud.points[i].data(), cloud.points[i].data() + 3);
        if (cloud.has_intensity()) rec.push_back(cloud.intensity[i]);
      }
      f.write(reinterpret_cast<const char*>(rec.data()),
              static_cast<std::streamsize>(rec.size() * sizeof(float)));
    } else {
      f.precision(9);
      for (std::size_t i = 0; i < cloud.size(); ++i) {
        const auto& p = cloud.points[i];
        f << p.x() << ' ' << p.y() << ' ' << p.z();
        if (cloud.has_intensity()) f << ' ' << cloud.intensity[i];
        f << '\n';
      }
    }
    f.close();
    if (!f) throw Error("failed writing '" + path + "' (disk full?)");
  }
  out.commit();
}

}  // namespace sonar3d
