// COLMAP text models (read_colmap_text): the input is two parts separated by a "--8<--" line,
// cameras.txt and images.txt. Every read camera also projects and unprojects its corners.
#include "fuzz_common.hpp"
#include "sonar3d/video/colmap.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto parts = sonar3d::fuzz::split(data, size, 2);
  const auto dir = sonar3d::fuzz::scratch() / "colmap";
  sonar3d::fuzz::write_file(dir / "cameras.txt", parts[0]);
  sonar3d::fuzz::write_file(dir / "images.txt", parts[1]);
  sonar3d::fuzz::run([&] {
    const sonar3d::PosedImages p = sonar3d::read_colmap_text(dir);
    for (const auto& [id, c] : p.cameras) {
      for (const Eigen::Vector2d px :
           {Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(c.width - 0.5, c.height - 0.5)}) {
        if (const auto ray = sonar3d::unproject(c, px)) sonar3d::project(c, *ray);
      }
    }
  });
  return 0;
}
