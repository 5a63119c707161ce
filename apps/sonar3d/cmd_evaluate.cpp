#include <fmt/core.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "commands.hpp"
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
    EvalConfig cfg;
    bool overwrite = false;
    double max_memory_gb = 0;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("cloud", o->cloud, "reconstructed point cloud (PLY, world frame)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("-t,--truth", o->truth,
                  "simulated dataset directory (its truth/, scored per object) or a mesh file")
      ->required();
  cmd->add_option("--coverage-radius", o->cfg.coverage_radius, "r_c in metres")
      ->capture_default_str();
  cmd->add_option("--outlier-radius", o->cfg.outlier_radius, "r_o in metres")
      ->capture_default_str();
  cmd->add_option("--samples-per-cm2", o->cfg.samples_per_cm2,
                  "surface samples per cm² for coverage (>= 1)")
      ->capture_default_str();
  cmd->add_option("--seed", o->cfg.seed, "surface sampling seed")->capture_default_str();
  cmd->add_option("--json", o->json,
                  "also write the metrics as JSON to this file (an existing one only if sonar3d "
                  "evaluate wrote it, with --overwrite)");
  add_overwrite_flag(cmd, o->overwrite, "metrics JSON sonar3d evaluate wrote earlier");
  add_max_memory_option(cmd, o->max_memory_gb);
  static const FlagNames kFlags = {{"coverage_radius", "--coverage-radius"},
                                   {"outlier_radius", "--outlier-radius"},
                                   {"samples_per_cm2", "--samples-per-cm2"}};
  cmd->callback([&run, o] {
    run = [o] {
      return with_flag_names(kFlags, [&] {
        o->cfg.validate();
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
        for (const auto& w : implausible_evaluation_radii(objects, o->cfg, "--coverage-radius",
                                                          "--outlier-radius")) {
          print_warning(w);
        }
        check_memory(estimate_evaluation_memory(cloud, objects, o->cfg, "--samples-per-cm2"),
                     memory_limit_bytes(o->max_memory_gb), "evaluate");
        const auto results = evaluate_objects(cloud, objects, o->cfg);
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
      });
    };
  });
}

}  // namespace sonar3d::cli
