#include "embree_device.hpp"

#include <string>

#include "sonar3d/core/error.hpp"

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

}  // namespace sonar3d::detail
