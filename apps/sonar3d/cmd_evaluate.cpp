#include <fmt/core.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "params_cli.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/eval/per_object.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/sim/simulation.hpp"

namespace sonar3d::cli {

void add_evaluate(CLI::App& app, const GlobalOptions& g, Runner& run) {
  auto* cmd = app.add_subcommand(
      "evaluate",
      "Score a reconstructed cloud against CAD ground truth (thesis sec. 4.5.2.1): unsigned "
      "median error, coverage within r_c, outliers beyond r_o, median/coverage ratio.");
  struct Opts {
    std::string cloud, truth, json;
    std::unique_ptr<ConfigOptions<EvalConfig>> config;
    bool overwrite = false;
    double max_memory_gb = 0;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("cloud", o->cloud, "reconstructed point cloud (PLY, world frame)")
      ->check(CLI::ExistingFile);
  cmd->add_option("-t,--truth", o->truth,
                  "simulated dataset directory (its truth/, scored per object) or a mesh file");
  cmd->add_option("--json", o->json,
                  "also write the metrics as JSON to this file (an existing one only if sonar3d "
                  "evaluate wrote it, with --overwrite)");
  add_overwrite_flag(cmd, o->overwrite, "metrics JSON sonar3d evaluate wrote earlier");
  add_max_memory_option(cmd, o->max_memory_gb);
  // Every setting (declared once, eval/metrics.hpp): its flag, --print-config, --config FILE.
  o->config = std::make_unique<ConfigOptions<EvalConfig>>(cmd);
  cmd->callback([&run, o] {
    // The cloud and --truth are required unless --print-config: a usage error (exit status 2).
    if (!o->config->print_requested()) {
      if (o->cloud.empty()) throw CLI::RequiredError("cloud");
      if (o->truth.empty()) throw CLI::RequiredError("-t,--truth");
    }
    run = [o] {
      // The library's errors name its fields ("coverage_radius"): the user reads the flag.
      // Errors in the settings name the user's flag (or the file, line and key).
      const EvalConfig cfg = with_flag_names(o->config->flag_names(), [&] {
        EvalConfig c = o->config->resolve("evaluate");
        c.validate();
        return c;
      });
      if (o->config->print_if_requested(cfg, "evaluate", "evaluate")) return 0;
      OutputFiles out(output_policy(o->overwrite, {o->cloud, o->truth}));
      const std::filesystem::path json =
          o->json.empty() ? std::filesystem::path()
                          : out.add(o->json, OutputKind::EvaluationJson, "--json");
      const PointCloud cloud = read_ply(o->cloud);
      std::vector<SceneObject> objects;
      if (std::filesystem::is_directory(o->truth)) {
        objects = read_truth(o->truth);
      } else {
        SceneObject obj;
        obj.name = std::filesystem::path(o->truth).stem().string();
        obj.mesh_world = load_mesh(o->truth);
        objects.push_back(std::move(obj));
      }
      for (const auto& w :
           implausible_evaluation_radii(objects, cfg, "--coverage-radius", "--outlier-radius")) {
        print_warning(w);
      }
      check_memory(estimate_evaluation_memory(cloud, objects, cfg, "--samples-per-cm2"),
                   memory_limit_bytes(o->max_memory_gb), "evaluate");
      const auto results = evaluate_objects(cloud, objects, cfg);
      nlohmann::json j = nlohmann::json::array();
      for (const auto& r : results) {
        fmt::print("{}\n", to_table(r.result, r.name));
        nlohmann::json item = nlohmann::json::parse(to_json(r.result));
        item["object"] = r.name;
        item["format"] = json_format_marker(OutputKind::EvaluationJson);
        j.push_back(item);
      }
      if (!o->json.empty()) {
        write_text_file(json.string(), j.dump(2) + "\n");
        out.commit();
      }
      return 0;
    };
  });
}

}  // namespace sonar3d::cli
