// sonar3d online: a recording replayed through the online map at its recorded rate, with the ROS 1
// node's queue, drops, latencies and diagnostics, without ROS (docs/online.md "Replaying a
// recording"). Library: pipeline/online_replay.hpp over pipeline/online_feed.hpp.
#include <fmt/core.h>

#include <atomic>
#include <cmath>
#include <csignal>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.hpp"
#include "online_node_config.hpp"
#include "params_cli.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/io/aris.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/navigation.hpp"
#include "sonar3d/pipeline/online_feed.hpp"
#include "sonar3d/pipeline/online_replay.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/recon/reconstruct.hpp"

namespace sonar3d::cli {
namespace {

std::atomic<int> g_online_signal{0};
extern "C" void on_online_signal(int sig) { g_online_signal = sig; }

// The feed's output as lines on standard error: one summary a publishing period.
class PrintSink : public OnlineFeedSink {
 public:
  explicit PrintSink(bool quiet) : quiet_(quiet) {}
  void cloud(const PointCloud&, double, const std::string&) override {}
  bool wants_elevation() const override { return false; }
  void elevation(const ElevationMap&, double, const std::string&) override {}
  void diagnostics(const std::string& stats_json) override {
    if (quiet_) return;
    const nlohmann::json s = nlohmann::json::parse(stats_json);
    const auto& c = s["latency_arrival_to_carved_ms"];
    fmt::print(
        stderr,
        "sonar3d online: received {}, carved {}, dropped {} (queue full {}, by the map "
        "{}), bad {}; cloud {} points of {} frames; arrival -> carved median {:.1f} ms, "
        "p95 {:.1f} ms\n",
        s["sonar_received"].get<std::size_t>(), s["map"].value("frames_used", std::size_t{0}),
        s["dropped_node_queue_full"].get<std::size_t>() +
            s["frames_dropped_by_map"].get<std::size_t>(),
        s["dropped_node_queue_full"].get<std::size_t>(),
        s["frames_dropped_by_map"].get<std::size_t>(), s["bad_sonar_messages"].get<std::size_t>(),
        s["cloud_points"].get<std::size_t>(), s["frames_in_cloud"].get<std::size_t>(),
        c["median"].get<double>(), c["p95"].get<double>());
  }
  void log(const std::string& line) override { fmt::print(stderr, "sonar3d online: {}\n", line); }
  void placements(const OnlinePlacements& found) override {
    if (quiet_) return;
    fmt::print(stderr,
               "sonar3d online: recognition {}: {} placements in the map of {} frames ({:.2f} s)\n",
               found.sequence, found.placements.size(), found.frames, found.seconds);
  }

 private:
  bool quiet_;
};

}  // namespace

void add_online(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "online",
      "Replay a recording (a dataset, or a ROS 1 bag) through the online map at its recorded "
      "rate, as the ROS 1 node `sonar3d ros` would receive it live: the same bounded queue, "
      "worker, drops and latencies; prints the node's diagnostics once a publishing period and "
      "its final statistics as JSON (docs/online.md). No ROS needed.");
  struct Opts {
    std::string input, sonar_topic = "/sonar3d/image", nav_topic = "/sonar3d/odom",
                       tf_topic = "/tf_static", mount, sonar, save_prefix, catalogue;
    double speed = 1.0, rate_hz = 1.0;
    std::size_t queue = 8;
    bool overwrite = false;
    std::unique_ptr<ConfigOptions<OnlineNodeConfig>> config;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("input", o->input, "dataset directory (sonar.yaml) or ROS 1 bag (.bag)")
      ->check(CLI::ExistingPath);
  cmd->add_option("--speed", o->speed,
                  "playing speed: 1 = the recorded rate, 2 = twice as fast, 0 = as fast as the "
                  "map takes the frames (nothing dropped for speed)")
      ->capture_default_str();
  cmd->add_option("--rate", o->rate_hz,
                  "publishing rate of the cloud (when it changed) and of the diagnostics, Hz")
      ->capture_default_str();
  cmd->add_option("--queue", o->queue,
                  "sonar messages waiting to be carved; when full the oldest is dropped and "
                  "counted, frames")
      ->capture_default_str();
  cmd->add_option("--sonar-topic", o->sonar_topic, "a bag's sonar topic")->capture_default_str();
  cmd->add_option("--nav-topic", o->nav_topic, "a bag's navigation topic")->capture_default_str();
  cmd->add_option("--tf-topic", o->tf_topic, "a bag's static transforms")->capture_default_str();
  cmd->add_option("--mount", o->mount,
                  "T_vehicle_sonar as x,y,z,roll,pitch,yaw (m, degrees), instead of the static "
                  "transforms");
  cmd->add_option("--sonar", o->sonar,
                  "sensor YAML (sonar.yaml fields): required for a bag of sensor_msgs/Image")
      ->check(CLI::ExistingFile);
  cmd->add_option("--save-prefix", o->save_prefix,
                  "at the end, write PREFIX.ply (cloud), PREFIX.tif (elevation GeoTIFF) and, with "
                  "--catalogue, PREFIX.placements.json together, as the node's ~save service "
                  "does");
  cmd->add_option("--catalogue", o->catalogue,
                  "catalogue YAML (as sonar3d recognize reads it): recognise its models every "
                  "--recognition-period s during the replay, off the carving thread, as `sonar3d "
                  "ros` does, and once more on the complete map at the end; the recognition's "
                  "settings: the recognize block of --config")
      ->check(CLI::ExistingFile);
  add_overwrite_flag(cmd, o->overwrite,
                     "a cloud, GeoTIFF and placements JSON at --save-prefix sonar3d wrote");
  // The settings of `sonar3d ros`: the carving, the recognition and its period.
  o->config = std::make_unique<ConfigOptions<OnlineNodeConfig>>(cmd);
  cmd->callback([&g, &run, o] {
    const FlagNames flags = online_node_flag_names(o->config->flag_names());
    run = [&g, o, flags]() -> int {
      return with_flag_names(flags, [&]() -> int {
        const OnlineNodeConfig cfg = o->config->resolve();
        const ReconstructConfig& rc = cfg.reconstruct;
        rc.validate();
        if (!o->catalogue.empty()) {
          cfg.recognize.validate();
          cfg.online_recognition.validate();
        }
        if (o->config->print_if_requested(cfg, "", "online")) return 0;
        require(!o->input.empty(), "online: give INPUT (a dataset directory or a ROS 1 bag)");
        if (rc.method != "carve") {
          throw Error("the online map carves (--method carve); '" + rc.method + "' is batch only");
        }
        require(std::isfinite(o->speed) && o->speed >= 0, "--speed must be >= 0");
        require(o->rate_hz > 0 && o->rate_hz <= 1000, "--rate must be in (0, 1000] Hz");
        require(o->queue >= 1, "--queue must be at least 1");
        OnlineFeedConfig fc;
        fc.sonar_topic = o->sonar_topic;
        fc.nav_topic = o->nav_topic;
        fc.tf_topic = o->tf_topic;
        if (!o->sonar.empty()) fc.described = read_sonar_description(o->sonar);
        if (!o->mount.empty()) fc.mount = parse_mounting(o->mount);
        fc.period_s = 1.0 / o->rate_hz;
        fc.queue = o->queue;
        fc.map.carve = rc.effective_carve();
        fc.map.validate();
        if (!o->catalogue.empty()) {
          read_catalogue(o->catalogue);  // a bad catalogue fails now, before the replay
          fc.catalogue = o->catalogue;
          fc.recognize = cfg.recognize;
          fc.recognition = cfg.online_recognition;
        }
        if (!o->save_prefix.empty()) {
          check_output(o->save_prefix + ".ply", OutputKind::PointCloud,
                       output_policy(o->overwrite, {o->input}), "--save-prefix");
          check_output(o->save_prefix + ".tif", OutputKind::GeoTiff,
                       output_policy(o->overwrite, {o->input}), "--save-prefix");
          if (!o->catalogue.empty()) {
            check_output(o->save_prefix + ".placements.json", OutputKind::PlacementsJson,
                         output_policy(o->overwrite, {o->input}), "--save-prefix");
          }
        }
        // A dataset replayed brings its own noise statistics for the Z-test, as reconstruct.
        if (std::filesystem::is_directory(o->input)) fc.noise = read_dataset(o->input).noise;
        PrintSink sink(g.quiet);
        OnlineFeed feed(fc, sink);
        std::signal(SIGINT, on_online_signal);
        std::signal(SIGTERM, on_online_signal);
        OnlineReplayOptions ro;
        ro.speed = o->speed;
        ro.stop = [] { return g_online_signal != 0; };
        ro.progress = !g.quiet;
        const OnlineReplayResult r = replay_into_feed(o->input, feed, fc, ro);
        if (!r.stopped) feed.drain();
        // The placements of the complete map (the periodic ones saw it growing).
        std::string found;
        if (!o->catalogue.empty() && r.sonar > 0 && !r.stopped) found = feed.recognize_now();
        std::string saved;
        if (!o->save_prefix.empty()) saved = feed.save(o->save_prefix, o->overwrite);
        feed.stop();
        const std::string stats = feed.stats_json();
        if (!g.quiet) {
          fmt::print(stderr,
                     "sonar3d online: replayed {} sonar, {} navigation and {} transform "
                     "messages ({:.1f} s recorded, speed {}){}{}{}\n",
                     r.sonar, r.navigation, r.tf, r.recorded_s, o->speed,
                     r.stopped ? "; stopped by a signal" : "",
                     found.empty() ? "" : "; recognised " + found,
                     saved.empty() ? "" : "; " + saved);
        }
        fmt::print("{}\n", stats);
        return 0;
      });
    };
  });
}

}  // namespace sonar3d::cli
