#include "embree_device.hpp"

#include <cstring>
#include <string>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"

namespace sonar3d::detail {
namespace {

struct DeviceHolder {
  RTCDevice device = nullptr;
  DeviceHolder() {
    device = rtcNewDevice(nullptr);
    if (!device) {
      throw Error("cannot start the Embree ray tracer (rtcNewDevice failed: error " +
                  std::to_string(static_cast<int>(rtcGetDeviceError(nullptr))) + ")");
    }
  }
  ~DeviceHolder() {
    if (device) rtcReleaseDevice(device);
  }
};

}  // namespace

RTCDevice embree_device() {
  static DeviceHolder holder;  // C++11 guarantees thread-safe initialisation
  return holder.device;
}

unsigned attach_mesh(RTCScene scene, const TriangleMesh& mesh, const std::string& what) {
  RTCDevice device = embree_device();
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.vertices.size()));
  auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0,
                                                             RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                                             mesh.triangles.size()));
  if (!v || !idx) {
    rtcReleaseGeometry(geom);
    throw Error(what + ": Embree could not allocate the buffers of its " +
                std::to_string(mesh.triangles.size()) + " triangles (error " +
                std::to_string(static_cast<int>(rtcGetDeviceError(device))) + ")");
  }
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const auto& p = mesh.vertices[i];
    if (!p.allFinite()) {
      rtcReleaseGeometry(geom);
      throw Error(what + ": vertex " + std::to_string(i) + " is not finite");
    }
    // Embree builds its bounds in float and asserts on coordinates beyond ~1e18.
    if (p.cwiseAbs().maxCoeff() > limits::kMaxCoordinate) {
      rtcReleaseGeometry(geom);
      throw Error(what + ": vertex " + std::to_string(i) +
                  " lies more than 1e7 m from the origin (check the mesh's unit and pose)");
    }
    std::memcpy(v + 3 * i, p.data(), 3 * sizeof(float));
  }
  const auto nv = static_cast<int>(mesh.vertices.size());
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const auto& t = mesh.triangles[i];
    if ((t.array() < 0).any() || (t.array() >= nv).any()) {
      rtcReleaseGeometry(geom);
      throw Error(what + ": triangle " + std::to_string(i) +
                  " indexes a vertex that does not exist");
    }
    idx[3 * i] = t[0];
    idx[3 * i + 1] = t[1];
    idx[3 * i + 2] = t[2];
  }
  rtcCommitGeometry(geom);
  const unsigned id = rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
  return id;
}

}  // namespace sonar3d::detail
