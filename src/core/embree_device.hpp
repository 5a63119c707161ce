#pragma once
// Internal: one process-wide Embree device shared by the simulator, evaluation and anything else
// that ray traces or queries closest points. Embree stays a private dependency of the library.
#include <embree3/rtcore.h>

namespace sonar3d::detail {

// Created on first use (thread-safe), released at exit. Throws Error if Embree cannot start.
RTCDevice embree_device();

}  // namespace sonar3d::detail
