// The files of video mapping (include/sonar3d/io/texture_io.hpp): colour images, textured meshes,
// the `views` convention of coloured clouds.
#include "sonar3d/io/texture_io.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/io/gltf.hpp"

namespace sonar3d {

namespace fs = std::filesystem;

RgbImage read_rgb_image(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw Error("image '" + path.string() + "' is not a file");
  cv::Mat m;
  try {
    m = cv::imread(path.string(), cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR);
  } catch (const cv::Exception& e) {
    throw Error("cannot read image '" + path.string() + "': " + e.what());
  }
  if (m.empty()) {
    throw Error("cannot read image '" + path.string() + "' (not an image format OpenCV reads)");
  }
  const int ch = m.channels();
  if (ch != 1 && ch != 3 && ch != 4) {
    throw Error("image '" + path.string() + "' has " + std::to_string(ch) +
                " channels (grey, BGR or BGRA expected)");
  }
  RgbImage img;
  img.width = m.cols;
  img.height = m.rows;
  img.rgb.resize(3 * static_cast<std::size_t>(m.cols) * m.rows);
  img.range_m.assign(static_cast<std::size_t>(m.cols) * m.rows,
                     std::numeric_limits<float>::infinity());
  // A table per encoded value: 8- and 16-bit are sRGB-encoded (made once; 65,536 powf calls for
  // 16 bits took longer than decoding a VGA image).
  auto make_lut = [](int levels) {
    std::vector<float> lut(static_cast<std::size_t>(levels));
    for (int k = 0; k < levels; ++k) lut[k] = srgb_to_linear(float(k) / float(levels - 1));
    return lut;
  };
  static const std::vector<float> lut8 = make_lut(256), lut16 = make_lut(65536);
  const std::vector<float>& lut = m.depth() == CV_8U ? lut8 : lut16;
  if (m.depth() != CV_8U && m.depth() != CV_16U && m.depth() != CV_32F) {
    throw Error("image '" + path.string() +
                "' has an unsupported pixel type (8-bit, 16-bit or 32-bit float expected)");
  }
  for (int v = 0; v < m.rows; ++v) {
    for (int u = 0; u < m.cols; ++u) {
      float bgr[3];
      for (int c = 0; c < 3; ++c) {
        const int k = ch == 1 ? 0 : c;
        switch (m.depth()) {
          case CV_8U:
            bgr[c] = lut[m.ptr<std::uint8_t>(v)[u * ch + k]];
            break;
          case CV_16U:
            bgr[c] = lut[m.ptr<std::uint16_t>(v)[u * ch + k]];
            break;
          default: {
            const float x = m.ptr<float>(v)[u * ch + k];
            if (!std::isfinite(x)) {
              throw Error("image '" + path.string() + "': pixel (" + std::to_string(u) + ", " +
                          std::to_string(v) + ") is not finite");
            }
            bgr[c] = x;
          }
        }
      }
      const std::size_t o = 3 * (static_cast<std::size_t>(v) * m.cols + u);
      img.rgb[o] = bgr[2];  // OpenCV's order is BGR
      img.rgb[o + 1] = bgr[1];
      img.rgb[o + 2] = bgr[0];
    }
  }
  return img;
}

void write_rgb_image(const fs::path& path, const RgbImage& image) {
  require(image.width > 0 && image.height > 0 &&
              image.rgb.size() == 3 * static_cast<std::size_t>(image.width) * image.height,
          "cannot write image '" + path.string() + "': its size and pixel count differ");
  cv::Mat m(image.height, image.width, CV_16UC3);
  for (int v = 0; v < image.height; ++v) {
    for (int u = 0; u < image.width; ++u) {
      const Eigen::Vector3f c = image.at(u, v);
      auto* p = m.ptr<std::uint16_t>(v) + 3 * u;
      for (int k = 0; k < 3; ++k) {
        p[2 - k] = static_cast<std::uint16_t>(std::lround(65535.0f * linear_to_srgb(c[k])));
      }
    }
  }
  std::vector<uchar> bytes;
  if (!cv::imencode(".png", m, bytes)) throw Error("cannot encode '" + path.string() + "'");
  AtomicPath out(path);
  {
    std::ofstream f(out.temp(), std::ios::binary);
    f.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
    f.close();
    if (!f) throw Error("failed writing '" + path.string() + "' (disk full?)");
  }
  out.commit();
}

std::vector<std::uint8_t> video_coloured(const PointCloud& cloud) {
  std::vector<std::uint8_t> out(cloud.size(), 0);
  if (!cloud.has_color()) return out;
  const PointProperty* views = cloud.property("views");
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const auto& c = cloud.color[i];
    out[i] = views != nullptr ? views->values[i] > 0 : (c[0] | c[1] | c[2]) != 0;
  }
  return out;
}

std::size_t TexturedMesh::coloured() const {
  return static_cast<std::size_t>(
      std::count_if(views.begin(), views.end(), [](std::uint32_t v) { return v > 0; }));
}

void write_textured_mesh_ply(const std::filesystem::path& path, const TexturedMesh& tm) {
  const TriangleMesh& m = tm.mesh;
  require(tm.color.size() == m.vertices.size(),
          "cannot write '" + path.string() + "': colour count differs from vertex count");
  AtomicPath out(path);
  {
    std::ofstream f(out.temp(), std::ios::binary);
    if (!f) throw Error("cannot open '" + path.string() + "' for writing");
    f << "ply\nformat binary_little_endian 1.0\ncomment sonar3d textured mesh, world frame, "
         "metres, sRGB vertex colours\nelement vertex "
      << m.vertices.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\n"
         "property uchar green\nproperty uchar blue\nelement face "
      << m.triangles.size() << "\nproperty list uchar int vertex_indices\nend_header\n";
    std::vector<char> buf(m.vertices.size() * 15 + m.triangles.size() * 13);
    char* p = buf.data();
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
      std::memcpy(p, m.vertices[i].data(), 12);
      p += 12;
      const std::array<std::uint8_t, 3> c =
          tm.views[i] ? linear_to_srgb8(tm.color[i]) : std::array<std::uint8_t, 3>{0, 0, 0};
      std::memcpy(p, c.data(), 3);
      p += 3;
    }
    for (const auto& t : m.triangles) {
      *p++ = 3;
      std::memcpy(p, t.data(), 12);
      p += 12;
    }
    f.write(buf.data(), static_cast<std::streamsize>(buf.size()));
    f.close();
    if (!f) throw Error("failed writing '" + path.string() + "' (disk full?)");
  }
  out.commit();
}

void write_textured_mesh_glb(const std::filesystem::path& path, const TexturedMesh& tm) {
  require(tm.color.size() == tm.mesh.vertices.size(),
          "cannot write '" + path.string() + "': colour count differs from vertex count");
  GltfScene scene;
  GltfMesh mesh;
  mesh.name = "textured";
  mesh.mesh = tm.mesh;
  mesh.base_color = Eigen::Vector4f(1, 1, 1, 1);  // the vertex colours as they are
  mesh.colors.resize(tm.color.size());
  for (std::size_t i = 0; i < tm.color.size(); ++i) {
    if (tm.views[i]) mesh.colors[i] = linear_to_srgb8(tm.color[i]);  // else black (resize)
  }
  scene.meshes.push_back(std::move(mesh));
  GltfNode node;
  node.name = "textured (world frame, ENU)";
  node.mesh = 0;
  node.matrix = enu_to_gltf();
  scene.nodes.push_back(node);
  scene.roots = {0};
  write_glb(path, scene);
}

}  // namespace sonar3d
