// Periodic recognition of an online map on its own thread (pipeline/online_recognition.hpp).
#include "sonar3d/pipeline/online_recognition.hpp"

#include <fmt/core.h>
#include <stdlib.h>

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "sonar3d/core/error.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/mapping/elevation_map.hpp"

namespace sonar3d {

namespace fs = std::filesystem;

void OnlineRecognitionConfig::validate() const { params::check(*this, "online recognition:"); }

namespace {

// A file name made of the model's name (letters, digits, '-', '_' kept; the rest '_').
std::string file_stem(const std::string& name) {
  std::string s;
  for (char ch : name) {
    const bool ok = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') ||
                    (ch >= '0' && ch <= '9') || ch == '-' || ch == '_';
    s += ok ? ch : '_';
  }
  return s.substr(0, 64);
}

}  // namespace

struct OnlineRecognizer::Impl {
  Catalogue catalogue;
  std::vector<ModelTemplate> models;
  std::vector<std::string> mesh_files;
  RecognizeConfig recognize;
  OnlineRecognitionConfig config;
  std::function<void(const OnlinePlacements&)> on_result;
  std::function<void(const std::string&)> log;
  fs::path mesh_dir;
  bool own_mesh_dir = false;

  // Only the thread that calls tick() reads and writes these.
  std::optional<Clock::time_point> due;
  std::size_t last_frames_started = 0;
  bool started_once = false;

  mutable std::mutex mutex;  // guards everything below
  std::condition_variable idle;
  bool running = false;
  std::thread worker;
  std::size_t started = 0, finished = 0, skipped_busy = 0, failed = 0;
  std::size_t map_too_small = 0;  // started, but every model's search patch exceeded the map
  std::vector<double> seconds;
  std::optional<OnlinePlacements> latest;

  ~Impl() {
    join();
    if (own_mesh_dir) {
      std::error_code ec;
      fs::remove_all(mesh_dir, ec);
    }
  }

  void join() {
    std::thread t;
    {
      std::lock_guard<std::mutex> lock(mutex);
      t.swap(worker);
    }
    if (t.joinable()) t.join();
  }

  // Starts a recognition on a new thread (none runs: the caller checked).
  void start(std::shared_ptr<const PointCloud> cloud, std::size_t frames, double stamp,
             const std::string& frame) {
    join();  // the previous run's thread has finished
    std::lock_guard<std::mutex> lock(mutex);
    running = true;
    ++started;
    started_once = true;
    last_frames_started = frames;
    worker = std::thread([this, cloud, frames, stamp, frame] { run(cloud, frames, stamp, frame); });
  }

  void run(std::shared_ptr<const PointCloud> cloud, std::size_t frames, double stamp,
           const std::string& frame) {
    OnlinePlacements out;
    out.frame = frame;
    out.frames = frames;
    out.points = cloud->size();
    out.stamp = stamp;
    bool ok = false;
    try {
      const auto t0 = Clock::now();
      // A map that grows: the 2D method refuses a model whose descriptor patch (eq. 6.8: r_model
      // + √½·period) does not fit in the map; such models wait for a larger map instead of
      // failing the whole recognition.
      std::vector<ModelTemplate> fitting;
      if (recognize.method == "2d") {
        ElevationMapConfig mc;
        mc.cell_m = recognize.two_d.recog_cell_m;
        const ElevationMap coarse = elevation_map_from_points(*cloud, mc);
        const double side = std::min(coarse.cols, coarse.rows) * coarse.cell_m;
        for (const ModelTemplate& mt : models) {
          const double r_patch = mt.radius_m + std::sqrt(0.5) * recognize.two_d.scan.period_m;
          if (2 * r_patch > side) {
            out.models_waiting.push_back(mt.name);
          } else {
            fitting.push_back(mt);
          }
        }
      } else {
        fitting = models;
      }
      if (fitting.empty()) {
        std::lock_guard<std::mutex> lock(mutex);
        ++map_too_small;
        running = false;
        idle.notify_all();
        return;
      }
      std::vector<Search3dRecord> searches3;
      const RecognitionResult r = sonar3d::recognize(*cloud, fitting, recognize, &searches3, false);
      out.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
      // The recognition's own threshold, shared by both methods (verify.hpp).
      const double threshold = recognize.two_d.verification.min_confidence;
      for (const Placement& p : r.placements) {
        if (!(p.confidence >= threshold)) continue;
        const auto it = std::find_if(models.begin(), models.end(),
                                     [&](const ModelTemplate& m) { return m.name == p.model; });
        if (it == models.end()) continue;
        const std::size_t k = static_cast<std::size_t>(it - models.begin());
        out.placements.push_back(p);
        out.model_index.push_back(k);
        out.mesh_files.push_back(mesh_files[k]);
        const ModelTemplate& mt = models[k];
        out.top_world.push_back(
            p.T_world_model *
            (p.scale * Eigen::Vector3d(mt.center_xy.x(), mt.center_xy.y(), mt.top_z)));
      }
      out.json = recognize_json(r, searches3,
                                fmt::format("sonar3d ros: the online map of {} frames ({} points, "
                                            "newest frame at {:.6f} s)",
                                            frames, cloud->size(), stamp),
                                catalogue.path, recognize);
      ok = true;
    } catch (const std::exception& e) {
      if (log) log(std::string("recognition failed: ") + e.what());
    }
    if (ok) {
      {
        std::lock_guard<std::mutex> lock(mutex);
        out.sequence = finished + 1;
      }
      try {
        if (on_result) on_result(out);
      } catch (const std::exception& e) {
        if (log) log(std::string("publishing the placements failed: ") + e.what());
      }
    }
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (ok) {
        ++finished;
        if (seconds.size() >= 10000) seconds.erase(seconds.begin(), seconds.begin() + 5000);
        seconds.push_back(out.seconds);
        latest = std::move(out);
      } else {
        ++failed;
      }
      running = false;
    }
    idle.notify_all();
  }
};

OnlineRecognizer::OnlineRecognizer(const std::string& catalogue_path,
                                   const RecognizeConfig& recognize,
                                   const OnlineRecognitionConfig& config,
                                   std::function<void(const OnlinePlacements&)> on_result,
                                   std::function<void(const std::string&)> log,
                                   const std::string& mesh_dir)
    : impl_(std::make_unique<Impl>()) {
  config.validate();
  recognize.validate();
  Impl& m = *impl_;
  m.recognize = recognize;
  m.config = config;
  m.on_result = std::move(on_result);
  m.log = std::move(log);
  m.catalogue = read_catalogue(catalogue_path);
  const bool three_d = recognize.method == "3d";
  for (const auto& entry : m.catalogue.models) {
    m.models.push_back(make_catalogue_template(
        m.catalogue, entry,
        three_d ? recognize.effective_3d().sampling : recognize.two_d.sampling));
  }
  if (mesh_dir.empty()) {
    std::string tmpl = (fs::temp_directory_path() / "sonar3d_models_XXXXXX").string();
    if (::mkdtemp(tmpl.data()) == nullptr) {
      throw Error("cannot create a temporary directory for the models' meshes under " +
                  fs::temp_directory_path().string());
    }
    m.mesh_dir = tmpl;
    m.own_mesh_dir = true;
  } else {
    m.mesh_dir = fs::absolute(mesh_dir);
    fs::create_directories(m.mesh_dir);
  }
  // The model's mesh as recognition placed it (model frame, the catalogue's scale): a marker
  // that shows this file at T_world_model · S(scale) shows what was found.
  for (std::size_t k = 0; k < m.models.size(); ++k) {
    const fs::path p = m.mesh_dir / fmt::format("{:03d}_{}.ply", k, file_stem(m.models[k].name));
    save_mesh(p.string(), m.models[k].mesh);
    m.mesh_files.push_back(p.string());
  }
}

OnlineRecognizer::~OnlineRecognizer() = default;

bool OnlineRecognizer::tick(Clock::time_point now, std::size_t frames,
                            std::shared_ptr<const PointCloud> cloud, double stamp,
                            const std::string& frame) {
  Impl& m = *impl_;
  const auto period =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(m.config.period_s));
  if (!m.due) m.due = now + period;  // the first period starts now
  if (now < *m.due) return false;
  // The next due time: one period on, or from now when the ticks fell behind.
  m.due = std::max(*m.due + period, now);
  if (!cloud || frames == 0 || (m.started_once && frames == m.last_frames_started)) return false;
  {
    std::lock_guard<std::mutex> lock(m.mutex);
    if (m.running) {
      ++m.skipped_busy;
      return false;
    }
  }
  m.start(std::move(cloud), frames, stamp, frame);
  return true;
}

bool OnlineRecognizer::run_now(std::size_t frames, std::shared_ptr<const PointCloud> cloud,
                               double stamp, const std::string& frame) {
  Impl& m = *impl_;
  wait();
  if (!cloud || frames == 0 || (m.started_once && frames == m.last_frames_started)) return false;
  m.start(std::move(cloud), frames, stamp, frame);
  wait();
  return true;
}

void OnlineRecognizer::reset() {
  impl_->started_once = false;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->latest.reset();
}

void OnlineRecognizer::wait() {
  Impl& m = *impl_;
  {
    std::unique_lock<std::mutex> lock(m.mutex);
    m.idle.wait(lock, [&] { return !m.running; });
  }
  m.join();
}

std::optional<OnlinePlacements> OnlineRecognizer::latest() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->latest;
}

std::string OnlineRecognizer::stats_json() const {
  const Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mutex);
  nlohmann::ordered_json j;
  j["period_s"] = m.config.period_s;
  j["running"] = m.running;
  j["started"] = m.started;
  j["finished"] = m.finished;
  j["skipped_busy"] = m.skipped_busy;
  j["failed"] = m.failed;
  j["map_smaller_than_models"] = m.map_too_small;
  j["placements"] = m.latest ? m.latest->placements.size() : 0;
  j["models_waiting"] = m.latest ? m.latest->models_waiting : std::vector<std::string>();
  j["last_frames"] = m.latest ? m.latest->frames : 0;
  std::vector<double> s = m.seconds;
  std::sort(s.begin(), s.end());
  nlohmann::ordered_json t;
  t["count"] = s.size();
  t["median"] = s.empty() ? 0.0 : s[s.size() / 2];
  t["p95"] = s.empty()
                 ? 0.0
                 : s[std::min(s.size() - 1,
                              static_cast<std::size_t>(0.95 * static_cast<double>(s.size())))];
  t["max"] = s.empty() ? 0.0 : s.back();
  j["seconds"] = t;
  return j.dump();
}

const Catalogue& OnlineRecognizer::catalogue() const { return impl_->catalogue; }
const std::vector<ModelTemplate>& OnlineRecognizer::models() const { return impl_->models; }
const std::vector<std::string>& OnlineRecognizer::mesh_files() const { return impl_->mesh_files; }
const RecognizeConfig& OnlineRecognizer::recognize_config() const { return impl_->recognize; }
const OnlineRecognitionConfig& OnlineRecognizer::config() const { return impl_->config; }

}  // namespace sonar3d
