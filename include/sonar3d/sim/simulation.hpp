#pragma once
// A whole simulation run described by a scene YAML file (docs/formats.md): the sensor, the
// objects, the trajectory, the noise model and the simulator settings; and the run itself, which
// writes a dataset directory with its ground truth.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "sonar3d/core/params.hpp"
#include "sonar3d/core/scene.hpp"
#include "sonar3d/core/sonar_spec.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/io/truth.hpp"  // read_truth: what simulate_dataset writes to truth/
#include "sonar3d/sim/dead_reckoning.hpp"
#include "sonar3d/sim/noise.hpp"
#include "sonar3d/sim/simulator.hpp"
#include "sonar3d/video/camera_dataset.hpp"
#include "sonar3d/video/render.hpp"

namespace sonar3d {

struct NoiseModelConfig {
  enum class Kind { None, Stripes, Images };
  Kind kind = Kind::None;
  StripeNoiseConfig stripes;
  std::string mean_path, std_path;  // Kind::Images: float TIFFs (range bins × beams)
  double scale = 1.0;               // multiplies mean and std (an SNR knob)
};

// Scene key `camera:` — a camera on the vehicle whose images the simulator renders (video
// mapping's ground truth) into the dataset's camera/ part, at rate_hz over the trajectory's span,
// from the true trajectory.
struct SimulatedCamera {
  CameraRig rig;
  double rate_hz = 2.0;  // frames per second
  CameraRenderConfig render;
};

struct SimulationSetup {
  std::string source;  // the scene file
  SonarSpec spec;
  SimulatorConfig simulator;
  Scene scene;
  Trajectory T_world_vehicle;  // one pose per frame
  NoiseModelConfig noise;
  // Scene key navigation_error: the logged navigation drifts (navigation.tum); truth/ keeps the
  // true trajectory (truth/navigation.tum).
  std::optional<DeadReckoningConfig> navigation_error;
  std::optional<SimulatedCamera> camera;
  unsigned long long seed = 1;
};

// sonar3d simulate's settings beside the scene file: a seed replacing the scene's, and whether a
// dataset in which no object is ever in view is written.
struct SimulateConfig {
  params::Maybe seed;  // none: the scene's seed; a whole number
  bool allow_empty = false;
  void validate() const;  // throws Error naming the field
};
template <class V>
void describe(SimulateConfig& c, V& v) {
  using params::param;
  v.field(c.seed, param("seed", "",
                        "random seed of the jitter and noise, a whole number (none: the scene's "
                        "seed)")
                      .range(0, 9007199254740992.0)
                      .flag("--seed"));
  v.field(c.allow_empty, param("allow_empty", "",
                               "write the dataset even when no object is ever in view (else an "
                               "error)")
                             .flag("--allow-empty"));
}

// Parses and validates a scene file; errors name the file, line and key.
SimulationSetup load_simulation_setup(const std::string& scene_yaml);

struct SimulationStats {
  std::size_t frames = 0;
  std::size_t rays = 0;
  double seconds = 0.0;
};

// Renders every frame and writes the dataset (frames, navigation, noise statistics when a noise
// model is used, and truth/ with each object's world-frame mesh) atomically to `out`.
SimulationStats simulate_dataset(const SimulationSetup& setup, const std::filesystem::path& out,
                                 bool progress);

// The noise statistics a setup applies (empty optional for Kind::None).
std::optional<NoiseImages> noise_images(const SimulationSetup& setup);

}  // namespace sonar3d
