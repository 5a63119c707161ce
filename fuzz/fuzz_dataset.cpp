// Dataset directory v1 (read_dataset, Dataset::load_frame, Dataset::T_world_sonar): the input is
// four parts separated by "--8<--" lines: sonar.yaml, frames.csv, navigation.tum and the bytes of
// frames/000000.png (also used as frames/000000.tiff). Every listed frame is loaded and posed.
#include "fuzz_common.hpp"
#include "sonar3d/io/dataset.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto parts = sonar3d::fuzz::split(data, size, 4);
  const auto dir = sonar3d::fuzz::scratch() / "dataset";
  sonar3d::fuzz::write_file(dir / "sonar.yaml", parts[0]);
  sonar3d::fuzz::write_file(dir / "frames.csv", parts[1]);
  sonar3d::fuzz::write_file(dir / "navigation.tum", parts[2]);
  sonar3d::fuzz::write_file(dir / "frames/000000.png", parts[3]);
  sonar3d::fuzz::write_file(dir / "frames/000000.tiff", parts[3]);
  sonar3d::fuzz::run([&] {
    const sonar3d::Dataset ds = sonar3d::read_dataset(dir);
    for (std::size_t i = 0; i < std::min<std::size_t>(ds.size(), 4); ++i) {
      sonar3d::fuzz::run([&] { ds.load_frame(i); });
      sonar3d::fuzz::run([&] { ds.T_world_sonar(i); });
    }
  });
  return 0;
}
