// NumPy .npz archives (parse_npz) and IDR/NeuS cameras files (read_neus_cameras): zip directory,
// stored and deflated entries, .npy headers, world_mat decomposition.
#include "fuzz_common.hpp"
#include "sonar3d/video/neus.hpp"
#include "sonar3d/video/npz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  sonar3d::fuzz::run([&] { sonar3d::parse_npz(data, size, "fuzz.npz"); });
  sonar3d::fuzz::run([&] { sonar3d::parse_npy(data, size, "fuzz.npy"); });
  const auto path = sonar3d::fuzz::scratch() / "cameras.npz";
  sonar3d::fuzz::write_file(path, std::string(reinterpret_cast<const char*>(data), size));
  sonar3d::fuzz::run([&] {
    for (const auto& cam : sonar3d::read_neus_cameras(path, sonar3d::NeusFrame::Normalized)) {
      sonar3d::intrinsics_from_K(cam.K, 640, 480);
    }
  });
  return 0;
}
