#pragma once
// Procedural meshes: primitives and the thesis' reference objects (sec. 4.5.1, Fig. 4.11).
// Every object stands on z = 0 (its base), centred on the z axis, z up, metres, outward normals.
#include <string>
#include <vector>

#include "sonar3d/core/mesh.hpp"

namespace sonar3d {

TriangleMesh make_sphere(double radius, int segments = 64);  // centred at origin
TriangleMesh make_cylinder(double radius, double height, int segments = 64, bool capped = true);
TriangleMesh make_box(double sx, double sy, double sz);  // centred at origin
TriangleMesh make_torus(double major_radius, double minor_radius, int major_segments = 48,
                        int minor_segments = 16);  // in the xy plane
TriangleMesh make_frustum(double bottom_width, double top_width,
                          double height);       // square pyramid frustum
TriangleMesh make_plane(double sx, double sy);  // z = 0, normal +z

// The four reference objects of Fig. 4.11 (sizes from the thesis; the rest documented in
// docs/formats.md):
TriangleMesh make_reference_sphere();  // 1 m diameter sphere resting on z = 0
TriangleMesh make_reference_tank();    // 50 cm diameter cylindrical tank with a wheel valve
TriangleMesh make_reference_pillar();  // pillar, 2 m wide base, 60 cm wide top
TriangleMesh make_reference_riser();   // 2 m oil-field riser structure, 40 cm buoyancies

// By name: sphere, tank, pillar, riser (reference objects) — throws Error listing the names.
TriangleMesh make_reference_object(const std::string& name);
std::vector<std::string> reference_object_names();

}  // namespace sonar3d
