#pragma once
// Imaging-sonar simulation by ray tracing (thesis sec. 2.5.2, imaging model eq. 2.13): a jittered
// ray grid over bearing × elevation (eq. 2.14–2.15), first-hit tracing so shadows are real,
// Lambert intensity (eq. 2.6) weighted by the beam pattern B(θ)² (eq. 2.8), range binning, gain.
#include <memory>
#include <random>

#include "sonar3d/core/scene.hpp"
#include "sonar3d/core/sonar_image.hpp"
#include "sonar3d/core/sonar_spec.hpp"

namespace sonar3d {

struct SimulatorConfig {
  double elevation_step_rad = 0.01 * M_PI / 180.0;  // θ_res: ray spacing across the aperture
  int rays_per_beam = 1;  // bearing sub-rays per beam (φ_res = beam width / rays_per_beam)
  bool jitter = true;     // eq. 2.14–2.15; false = regular grid (shows aliasing, Fig. 2.20)
  double gain = 2.0;      // linear intensity scale applied before quantisation
  int num_threads = 0;    // 0 = all cores (TBB)
  void validate() const;  // throws Error naming the field
};

// Builds the Embree scene once; render() is then called per pose, possibly from several threads
// with distinct generators.
class Simulator {
 public:
  Simulator(const Scene& scene, const SonarSpec& spec, const SimulatorConfig& config);
  ~Simulator();
  Simulator(const Simulator&) = delete;
  Simulator& operator=(const Simulator&) = delete;

  // Noise-free linear image seen from T_world_sonar. `seed` drives the jitter; the same seed gives
  // the same image whatever the thread count.
  SonarImage render(const Eigen::Isometry3d& T_world_sonar, unsigned long long seed) const;

  // Number of rays one render() traces.
  std::size_t rays_per_image() const;
  const SonarSpec& spec() const { return spec_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  SonarSpec spec_;
  SimulatorConfig config_;
};

}  // namespace sonar3d
