// Procedural meshes: primitives and the four reference objects of the thesis (sec. 4.5.1,
// Fig. 4.11).
//
// Conventions (GUIDE.md sec. 3): metres, z up, triangles counter-clockwise seen from outside so
// normals point outward. Sphere, box and torus are centred on the origin; cylinder and frustum have
// their base on z = 0 and their axis on z (so they stack without offsets); the plane lies in z = 0
// facing +z. Sphere, cylinder (capped), box, torus and frustum are closed 2-manifolds: every edge
// is shared by exactly two triangles, once in each direction. Tessellated curved surfaces are
// inscribed (vertices on the true surface), so their area and volume are slightly below the
// analytic values: with 64 segments about 0.2 % for the area of a sphere or cylinder.
//
// Reference objects (Fig. 4.11). The thesis gives one size for each; everything else is our choice,
// listed here. Each stands on z = 0 and is centred on the z axis. They are assembled from closed
// parts that touch or overlap (e.g. a spoke entering the hub), so each part is watertight and
// outward-facing but the whole is not one manifold; this is harmless for ray casting.
//
//   sphere  "1m diameter sphere" (thesis). UV sphere, radius 0.5 m, centre (0, 0, 0.5), resting on
//           z = 0. 128 x 64 segments. Bounding box 1.0 x 1.0 x 1.0 m.
//   tank    "50cm diameter cylindrical tank with a wheel valve" (thesis). The thesis also calls it
//           "the bottle" (sec. 4.5.2.3), so the valve sits on top as on a gas bottle:
//             body       cylinder, diameter 0.50 m, z 0 .. 1.00 m (capped)
//             stem       cylinder, diameter 0.06 m, z 1.00 .. 1.17 m
//             hub        cylinder, diameter 0.09 m, z 1.14 .. 1.20 m
//             handwheel  torus in a horizontal plane at z = 1.17 m, rim radius 0.15 m (to the tube
//                        centre), tube diameter 0.06 m: outer diameter 0.36 m
//             spokes     4 cylinders, diameter 0.024 m, along +-x and +-y from the axis to the rim
//           Bounding box 0.50 x 0.50 x 1.20 m.
//   pillar  "Pillar model with a 2m wide base and a 60cm wide top" (thesis). A bridge-pier style
//           pillar: a square footing and a tapering square column, which gives the horizontal
//           surfaces the thesis mentions for this object (sec. 4.5.2.3):
//             footing    box 2.00 x 2.00 m, z 0 .. 0.40 m
//             column     square frustum, 1.00 m wide at z = 0.40 m, 0.60 m wide at z = 2.50 m
//           Bounding box 2.00 x 2.00 x 2.50 m.
//   riser   "2m large oil-field structure mounted on a vertical axis exhibiting 40cm diameter
//           buoyancies" (thesis); its "side tubes" are mentioned in sec. 5.6.1 (Fig. 5.5-k):
//             mudmat     box 1.00 x 1.00 m, z 0 .. 0.10 m
//             riser      vertical pipe, diameter 0.25 m, z 0.10 .. 2.00 m
//             side tubes 2 horizontal pipes along x, diameter 0.10 m, x -0.80 .. 0.80 m, at
//                        z = 1.20 m and z = 1.60 m
//             buoyancies 2 vertical closed cylinders, diameter 0.40 m, z 1.00 .. 1.80 m, axes at
//                        x = +-0.80 m (outer faces at x = +-1.00 m)
//           Bounding box 2.00 x 1.00 x 2.00 m (x from -1.0 to 1.0, y from -0.5 to 0.5).
//
// Triangle counts: sphere 16 128, tank 2 816, pillar 24, riser 1 036 (all below 40 k).
#include "sonar3d/core/reference_objects.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/units.hpp"

namespace sonar3d {
namespace {

void require_segments(int segments, int minimum, const char* name) {
  if (segments < minimum) {
    throw Error("parameter '" + std::string(name) + "' must be at least " +
                std::to_string(minimum) + ", got " + std::to_string(segments));
  }
}

Eigen::Vector3f vec(double x, double y, double z) { return Eigen::Vector3d(x, y, z).cast<float>(); }

// Adds the two triangles of quad a-b-c-d given counter-clockwise seen from outside.
void add_quad(TriangleMesh* m, int a, int b, int c, int d) {
  m->triangles.emplace_back(a, b, c);
  m->triangles.emplace_back(a, c, d);
}

TriangleMesh placed(TriangleMesh mesh, const Eigen::Isometry3d& T) {
  mesh.transform(T);
  return mesh;
}

Eigen::Isometry3d translation(double x, double y, double z) {
  return Eigen::Isometry3d(Eigen::Translation3d(x, y, z));
}

// A cylinder of the given radius and length lying along +x, starting at x = 0 (rotating +z onto +x
// is a +90 deg turn about y).
TriangleMesh make_x_cylinder(double radius, double length, int segments) {
  return placed(make_cylinder(radius, length, segments),
                Eigen::Isometry3d(Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitY())));
}

}  // namespace

TriangleMesh make_sphere(double radius, int segments) {
  require_positive(radius, "radius", "m");
  require_segments(segments, 3, "segments");
  const int slices = segments;                   // around z
  const int stacks = std::max(2, segments / 2);  // pole to pole
  TriangleMesh m;
  m.vertices.push_back(vec(0, 0, radius));  // north pole: index 0
  for (int i = 1; i < stacks; ++i) {
    const double theta = kPi * i / stacks;  // polar angle from +z
    for (int j = 0; j < slices; ++j) {
      const double phi = 2 * kPi * j / slices;
      m.vertices.push_back(vec(radius * std::sin(theta) * std::cos(phi),
                               radius * std::sin(theta) * std::sin(phi), radius * std::cos(theta)));
    }
  }
  const int south = static_cast<int>(m.vertices.size());
  m.vertices.push_back(vec(0, 0, -radius));
  auto ring = [slices](int i, int j) { return 1 + (i - 1) * slices + (j % slices); };
  for (int j = 0; j < slices; ++j) {
    m.triangles.emplace_back(0, ring(1, j), ring(1, j + 1));
    for (int i = 1; i + 1 < stacks; ++i) {
      add_quad(&m, ring(i, j), ring(i + 1, j), ring(i + 1, j + 1), ring(i, j + 1));
    }
    m.triangles.emplace_back(south, ring(stacks - 1, j + 1), ring(stacks - 1, j));
  }
  return m;
}

TriangleMesh make_cylinder(double radius, double height, int segments, bool capped) {
  require_positive(radius, "radius", "m");
  require_positive(height, "height", "m");
  require_segments(segments, 3, "segments");
  TriangleMesh m;
  for (int j = 0; j < segments; ++j) {  // bottom ring 0..n-1, top ring n..2n-1
    const double phi = 2 * kPi * j / segments;
    m.vertices.push_back(vec(radius * std::cos(phi), radius * std::sin(phi), 0));
  }
  for (int j = 0; j < segments; ++j) {
    const Eigen::Vector3f b = m.vertices[j];
    m.vertices.push_back(Eigen::Vector3f(b.x(), b.y(), static_cast<float>(height)));
  }
  auto bot = [segments](int j) { return j % segments; };
  auto top = [segments](int j) { return segments + j % segments; };
  for (int j = 0; j < segments; ++j) add_quad(&m, bot(j), bot(j + 1), top(j + 1), top(j));
  if (capped) {
    const int cb = static_cast<int>(m.vertices.size());
    m.vertices.push_back(vec(0, 0, 0));
    m.vertices.push_back(vec(0, 0, height));
    for (int j = 0; j < segments; ++j) {
      m.triangles.emplace_back(cb, bot(j + 1), bot(j));      // faces -z
      m.triangles.emplace_back(cb + 1, top(j), top(j + 1));  // faces +z
    }
  }
  return m;
}

TriangleMesh make_box(double sx, double sy, double sz) {
  require_positive(sx, "sx", "m");
  require_positive(sy, "sy", "m");
  require_positive(sz, "sz", "m");
  TriangleMesh m;
  // Corner i has x, y, z at the high side when bit 0, 1, 2 of i is set.
  for (int i = 0; i < 8; ++i) {
    m.vertices.push_back(
        vec((i & 1 ? 0.5 : -0.5) * sx, (i & 2 ? 0.5 : -0.5) * sy, (i & 4 ? 0.5 : -0.5) * sz));
  }
  add_quad(&m, 0, 2, 3, 1);  // -z
  add_quad(&m, 4, 5, 7, 6);  // +z
  add_quad(&m, 0, 1, 5, 4);  // -y
  add_quad(&m, 3, 2, 6, 7);  // +y
  add_quad(&m, 2, 0, 4, 6);  // -x
  add_quad(&m, 1, 3, 7, 5);  // +x
  return m;
}

TriangleMesh make_torus(double major_radius, double minor_radius, int major_segments,
                        int minor_segments) {
  require_positive(major_radius, "major_radius", "m");
  require_positive(minor_radius, "minor_radius", "m");
  if (minor_radius >= major_radius) {
    // A horn or spindle torus intersects itself and has no well-defined outside.
    throw Error("parameter 'minor_radius' (" + std::to_string(minor_radius) +
                " m) must be smaller than 'major_radius' (" + std::to_string(major_radius) + " m)");
  }
  require_segments(major_segments, 3, "major_segments");
  require_segments(minor_segments, 3, "minor_segments");
  TriangleMesh m;
  for (int i = 0; i < major_segments; ++i) {
    const double u = 2 * kPi * i / major_segments;  // around z
    for (int j = 0; j < minor_segments; ++j) {
      const double v = 2 * kPi * j / minor_segments;  // around the tube, 0 = outer equator
      const double rho = major_radius + minor_radius * std::cos(v);
      m.vertices.push_back(vec(rho * std::cos(u), rho * std::sin(u), minor_radius * std::sin(v)));
    }
  }
  auto idx = [&](int i, int j) {
    return (i % major_segments) * minor_segments + (j % minor_segments);
  };
  // d/du x d/dv points outward, so (i, j) -> (i+1, j) -> (i+1, j+1) is counter-clockwise.
  for (int i = 0; i < major_segments; ++i) {
    for (int j = 0; j < minor_segments; ++j) {
      add_quad(&m, idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
    }
  }
  return m;
}

TriangleMesh make_frustum(double bottom_width, double top_width, double height) {
  require_positive(bottom_width, "bottom_width", "m");
  require_non_negative(top_width, "top_width", "m");
  require_positive(height, "height", "m");
  TriangleMesh m;
  const double b = 0.5 * bottom_width, t = 0.5 * top_width;
  m.vertices = {vec(-b, -b, 0), vec(b, -b, 0), vec(-b, b, 0), vec(b, b, 0)};
  if (top_width == 0.0) {  // a pyramid: one apex instead of a degenerate top face
    m.vertices.push_back(vec(0, 0, height));
    m.triangles = {{0, 2, 3}, {0, 3, 1}, {0, 1, 4}, {1, 3, 4}, {3, 2, 4}, {2, 0, 4}};
    return m;
  }
  for (const auto& v :
       {vec(-t, -t, height), vec(t, -t, height), vec(-t, t, height), vec(t, t, height)}) {
    m.vertices.push_back(v);
  }
  // Same corner numbering and faces as make_box.
  add_quad(&m, 0, 2, 3, 1);
  add_quad(&m, 4, 5, 7, 6);
  add_quad(&m, 0, 1, 5, 4);
  add_quad(&m, 3, 2, 6, 7);
  add_quad(&m, 2, 0, 4, 6);
  add_quad(&m, 1, 3, 7, 5);
  return m;
}

TriangleMesh make_plane(double sx, double sy) {
  require_positive(sx, "sx", "m");
  require_positive(sy, "sy", "m");
  TriangleMesh m;
  m.vertices = {vec(-0.5 * sx, -0.5 * sy, 0), vec(0.5 * sx, -0.5 * sy, 0),
                vec(0.5 * sx, 0.5 * sy, 0), vec(-0.5 * sx, 0.5 * sy, 0)};
  add_quad(&m, 0, 1, 2, 3);  // counter-clockwise seen from +z
  return m;
}

// Dimensions of the reference objects: see the table at the top of this file.

TriangleMesh make_reference_sphere() {
  // Fig. 4.11-a: 1 m diameter.
  return placed(make_sphere(0.5, 128), translation(0, 0, 0.5));
}

TriangleMesh make_reference_tank() {
  // Fig. 4.11-b: 50 cm diameter tank; the wheel valve on top.
  constexpr double kBodyRadius = 0.25, kBodyHeight = 1.0;
  constexpr double kWheelZ = 1.17, kRimRadius = 0.15, kTubeRadius = 0.03;
  TriangleMesh m = make_cylinder(kBodyRadius, kBodyHeight, 96);
  m.append(placed(make_cylinder(0.03, kWheelZ - kBodyHeight, 24), translation(0, 0, kBodyHeight)));
  m.append(placed(make_cylinder(0.045, 0.06, 24), translation(0, 0, kWheelZ - 0.03)));
  m.append(placed(make_torus(kRimRadius, kTubeRadius, 64, 16), translation(0, 0, kWheelZ)));
  for (int k = 0; k < 4; ++k) {
    const Eigen::Isometry3d T =
        translation(0, 0, kWheelZ) * Eigen::AngleAxisd(k * kPi / 2, Eigen::Vector3d::UnitZ());
    m.append(placed(make_x_cylinder(0.012, kRimRadius, 12), T));
  }
  return m;
}

TriangleMesh make_reference_pillar() {
  // Fig. 4.11-c: 2 m wide base, 60 cm wide top.
  constexpr double kFootingWidth = 2.0, kFootingHeight = 0.4;
  constexpr double kColumnBottom = 1.0, kColumnTop = 0.6, kTopZ = 2.5;
  TriangleMesh m = placed(make_box(kFootingWidth, kFootingWidth, kFootingHeight),
                          translation(0, 0, 0.5 * kFootingHeight));
  m.append(placed(make_frustum(kColumnBottom, kColumnTop, kTopZ - kFootingHeight),
                  translation(0, 0, kFootingHeight)));
  return m;
}

TriangleMesh make_reference_riser() {
  // Fig. 4.11-d: 2 m large structure on a vertical axis with 40 cm diameter buoyancies.
  constexpr double kMudmatWidth = 1.0, kMudmatHeight = 0.1;
  constexpr double kRiserRadius = 0.125, kTopZ = 2.0;
  constexpr double kBuoyancyRadius = 0.2, kBuoyancyX = 0.8, kBuoyancyZ0 = 1.0, kBuoyancyZ1 = 1.8;
  constexpr double kTubeRadius = 0.05;
  TriangleMesh m = placed(make_box(kMudmatWidth, kMudmatWidth, kMudmatHeight),
                          translation(0, 0, 0.5 * kMudmatHeight));
  m.append(placed(make_cylinder(kRiserRadius, kTopZ - kMudmatHeight, 64),
                  translation(0, 0, kMudmatHeight)));
  for (const double z : {1.2, 1.6}) {
    m.append(
        placed(make_x_cylinder(kTubeRadius, 2 * kBuoyancyX, 32), translation(-kBuoyancyX, 0, z)));
  }
  for (const double x : {-kBuoyancyX, kBuoyancyX}) {
    m.append(placed(make_cylinder(kBuoyancyRadius, kBuoyancyZ1 - kBuoyancyZ0, 64),
                    translation(x, 0, kBuoyancyZ0)));
  }
  return m;
}

std::vector<std::string> reference_object_names() { return {"sphere", "tank", "pillar", "riser"}; }

TriangleMesh make_reference_object(const std::string& name) {
  if (name == "sphere") return make_reference_sphere();
  if (name == "tank") return make_reference_tank();
  if (name == "pillar") return make_reference_pillar();
  if (name == "riser") return make_reference_riser();
  std::ostringstream os;
  os << "unknown reference object '" << printable(name) << "'; known objects:";
  const auto names = reference_object_names();
  for (size_t i = 0; i < names.size(); ++i) os << (i ? ", " : " ") << names[i];
  throw Error(os.str());
}

}  // namespace sonar3d
