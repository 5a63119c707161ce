#pragma once
// Periodic recognition of a catalogue's models in an online map (issue 25; docs/online.md
// "Recognised placements"): the part of `sonar3d ros --catalogue` that has no ROS type in it.
//
//   OnlineRecognizer rec(catalogue_path, recognize_config, config, on_result, log);
//   rec.tick(now, frames, cloud_snapshot, stamp);   // every publishing period, from the feed
//   ...                                             // on_result(placements) when one finishes
//
// A recognition (recog/recognize.hpp: the same call and configuration as `sonar3d recognize`)
// runs on the recognizer's own thread, on a snapshot of the cloud (a shared, immutable copy), so
// that the thread which carves never waits for it. One recognition at a time: when the period
// comes while the previous one still runs, that period is skipped and counted. A period that
// comes with no frame carved since the last recognition starts none (nothing new to find).
#include <Eigen/Geometry>
#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sonar3d/core/params.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/recog/model.hpp"
#include "sonar3d/recog/recognize.hpp"

namespace sonar3d {

struct OnlineRecognitionConfig {
  double period_s = 10.0;  // how often the current map is recognised, s
  void validate() const;   // throws Error naming the field and its flag
};

template <class V>
void describe(OnlineRecognitionConfig& c, V& v) {
  using params::param;
  v.field(c.period_s,
          param("period_s", "s",
                "with --catalogue: how often the current map is recognised (checked at each "
                "publishing period; a period that comes while the previous recognition still "
                "runs is skipped and counted)")
              .range(0.01, 86400)
              .flag("--recognition-period"));
}

// One recognition of the online map.
struct OnlinePlacements {
  // The placements found, each at or above the recognition's own threshold
  // (verification.min_confidence), in the cloud's frame.
  std::vector<Placement> placements;
  // Per placement: the index of its model in OnlineRecognizer::models() and the PLY file the
  // recognizer wrote with that model's mesh (model frame, the catalogue's scale applied).
  std::vector<std::size_t> model_index;
  std::vector<std::string> mesh_files;
  // Per placement: the top of the placed model above its horizontal centre (world frame), where
  // a label goes.
  std::vector<Eigen::Vector3d> top_world;
  // Models left out of this recognition because the map is still smaller than their search
  // patch (the 2D method's rule, eq. 6.8); they are searched once the map is large enough.
  std::vector<std::string> models_waiting;
  std::size_t sequence = 0;  // 1 for the first recognition that finished, then 2, ...
  std::size_t frames = 0;    // frames carved into the cloud recognised
  std::size_t points = 0;    // points of that cloud
  double stamp = 0;          // header time of the newest frame in that cloud, s
  std::string frame;         // the cloud's frame (tick's `frame`)
  double seconds = 0;        // wall time of the recognition, s
  std::string json;          // the placements file (as `sonar3d recognize -o` writes it)
};

class OnlineRecognizer {
 public:
  using Clock = std::chrono::steady_clock;
  // Reads the catalogue and prepares its models (the sampling of the configured method), and
  // writes each model's mesh as PLY into `mesh_dir` (created; "" = a new directory under the
  // system's temporary directory, removed with the recognizer). Throws Error naming the
  // catalogue or the setting. `on_result` and `log` are called on the recognizer's thread.
  OnlineRecognizer(const std::string& catalogue_path, const RecognizeConfig& recognize,
                   const OnlineRecognitionConfig& config,
                   std::function<void(const OnlinePlacements&)> on_result,
                   std::function<void(const std::string&)> log, const std::string& mesh_dir = "");
  ~OnlineRecognizer();  // wait()
  OnlineRecognizer(const OnlineRecognizer&) = delete;
  OnlineRecognizer& operator=(const OnlineRecognizer&) = delete;

  // Called regularly (the feed: at every publishing period). The first call starts the clock;
  // when a period has passed since the last due time: skipped and counted if a recognition
  // still runs, nothing if `frames` equals the frames of the last recognition started, else a
  // recognition of `cloud` (carved from `frames` frames, newest stamp `stamp`, in `frame`)
  // starts on the recognizer's thread. Returns whether one started. Cheap; never waits for a
  // recognition.
  bool tick(Clock::time_point now, std::size_t frames, std::shared_ptr<const PointCloud> cloud,
            double stamp, const std::string& frame = "");

  // The map was cleared: the last placements are forgotten (latest() is none until the next
  // recognition finishes; one still running on the old map finishes and counts as the latest),
  // and the next period recognises whatever is carved by then, even the same number of frames as
  // the last recognition.
  void reset();

  // Waits for a running recognition, then recognises `cloud` now and waits for it (the end of a
  // replay: the complete map), unless it has the frames of the last recognition started.
  // Returns whether one ran.
  bool run_now(std::size_t frames, std::shared_ptr<const PointCloud> cloud, double stamp,
               const std::string& frame = "");

  // Waits until no recognition runs.
  void wait();

  // The last recognition that finished (none yet: nullopt).
  std::optional<OnlinePlacements> latest() const;

  // Counters as one JSON object: started, finished, skipped_busy, failed,
  // map_smaller_than_models (started on a map smaller than every model's search patch: nothing
  // to search yet), placements, models_waiting and last_frames of the last, seconds {count,
  // median, p95, max} over the recognitions that finished.
  std::string stats_json() const;

  const Catalogue& catalogue() const;
  const std::vector<ModelTemplate>& models() const;
  const std::vector<std::string>& mesh_files() const;  // per model, absolute paths
  const RecognizeConfig& recognize_config() const;
  const OnlineRecognitionConfig& config() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sonar3d
