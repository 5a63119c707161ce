#pragma once
// The dataset directory, version 1 (docs/formats.md):
//   sonar.yaml  frames.csv  frames/NNNNNN.png|.tiff  navigation.tum  [noise/]  [truth/]
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sonar3d/core/sonar_image.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/core/trajectory.hpp"

namespace sonar3d {

inline constexpr int kDatasetVersion = 1;

struct FrameRecord {
  int index = 0;
  double timestamp = 0.0;  // s, on the navigation clock
  std::string file;        // relative to the dataset root
};

// Per-pixel open-water noise statistics (sec. 2.5.2), in linear intensity units.
struct NoiseImages {
  SonarImage mean;
  SonarImage std;
};

struct Dataset {
  std::filesystem::path root;  // the directory it was read from
  SonarSpec spec;
  std::vector<FrameRecord> frames;
  Trajectory navigation;  // T_world_vehicle
  std::optional<NoiseImages> noise;

  std::size_t size() const { return frames.size(); }
  // Reads frame i, checks its size against the spec; linear float intensities.
  SonarImage load_frame(std::size_t i) const;
  // Sonar pose of frame i: navigation interpolated at its timestamp × T_vehicle_sonar.
  // Throws Error naming the frame when the time is outside the navigation span.
  Eigen::Isometry3d T_world_sonar(std::size_t i) const;
  bool has_truth() const;
  std::filesystem::path truth_dir() const { return root / "truth"; }
};

// A frames.csv (index,timestamp,file; the sonar's and the camera's): indices unique, timestamps
// finite and never going back, files relative paths inside the dataset. Errors name file and line.
std::vector<FrameRecord> read_frames_csv(const std::filesystem::path& path);
std::string frames_csv_text(const std::vector<FrameRecord>& frames);

// Reads sonar.yaml, frames.csv, navigation.tum and noise/ (frames are read on demand). Errors name
// the file, line and key.
Dataset read_dataset(const std::filesystem::path& dir);

// Writes a dataset frame by frame into a temporary directory, renamed into place by commit().
// Destroying an uncommitted writer removes everything it wrote.
class DatasetWriter {
 public:
  enum class ImageFormat { Png, Tiff };
  DatasetWriter(const std::filesystem::path& dir, const SonarSpec& spec,
                ImageFormat format = ImageFormat::Png);
  ~DatasetWriter();
  // Appends a frame; its size must match the spec. Returns its index.
  int add_frame(const SonarImage& image);
  void set_navigation(const Trajectory& T_world_vehicle);
  void set_noise(const NoiseImages& noise);
  // Directory (inside the temporary dataset) where ground truth can be written.
  std::filesystem::path truth_dir();
  // Directory (inside the temporary dataset) for an optional part, e.g. "camera".
  std::filesystem::path part_dir(const std::string& name);
  void commit();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Sonar description as YAML text (the sonar.yaml body) and back. `where` names the source in
// errors.
std::string sonar_spec_to_yaml(const SonarSpec& spec);

// Image IO in the dataset's encodings: 8/16-bit PNG scaled by spec.intensity_scale, or float32
// TIFF holding linear intensities as they are.
SonarImage read_sonar_image(const std::string& path, const SonarSpec& spec);
void write_sonar_image(const std::string& path, const SonarImage& image, const SonarSpec& spec);
// Float32 single-channel TIFF (noise statistics).
SonarImage read_float_image(const std::string& path);
void write_float_image(const std::string& path, const SonarImage& image);

}  // namespace sonar3d
