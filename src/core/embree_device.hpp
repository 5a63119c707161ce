#pragma once
// Internal: one process-wide Embree device shared by the simulator, evaluation and anything else
// that ray traces or queries closest points. Embree stays a private dependency of the library.
#include <embree3/rtcore.h>

#include <string>

#include "sonar3d/core/mesh.hpp"

namespace sonar3d::detail {

// Created on first use (thread-safe), released at exit. Throws Error if Embree cannot start.
RTCDevice embree_device();

// Adds `mesh` to `scene` as a triangle geometry and returns its geometry id. Throws Error naming
// `what` for a non-finite vertex, a vertex beyond ±1e7 m (Embree builds its bounds in float) or an
// index out of range; nothing is attached then.
unsigned attach_mesh(RTCScene scene, const TriangleMesh& mesh, const std::string& what);

}  // namespace sonar3d::detail
