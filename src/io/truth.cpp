// The ground truth of a simulated dataset (include/sonar3d/io/truth.hpp).
#include "sonar3d/io/truth.hpp"

#include <string>

#include "sonar3d/core/error.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/io/yaml_config.hpp"

namespace fs = std::filesystem;

namespace sonar3d {

std::vector<SceneObject> read_truth(const fs::path& dir) {
  const fs::path yaml_path = dir / "truth" / "scene.yaml";
  if (!fs::exists(yaml_path)) {
    throw Error("'" + dir.string() + "' has no ground truth (truth/scene.yaml is missing)");
  }
  const std::string file = yaml_path.string();
  YAML::Node root = yaml::load_file(file);
  const YAML::Node objs = root["objects"];
  if (!objs || !objs.IsSequence()) throw Error(file + ": 'objects' must be a list");
  std::vector<SceneObject> out;
  for (std::size_t i = 0; i < objs.size(); ++i) {
    const std::string ctx = "objects[" + std::to_string(i) + "]";
    SceneObject o;
    o.name = yaml::get_string(objs[i], "name", "", file, ctx);
    o.reflectivity = yaml::get_double(objs[i], "reflectivity", 0.5, file, ctx);
    try {  // datasets written before kinds existed: structures
      o.kind = object_kind_from_string(yaml::get_string(objs[i], "kind", "structure", file, ctx));
    } catch (const Error& e) {
      throw Error(yaml::where(file, objs[i], ctx + ".kind") + ": " + e.what());
    }
    if (objs[i]["color"]) {
      const auto c = yaml::get_vector(objs[i], "color", 3, file, ctx);
      o.color = Eigen::Vector3d(c[0], c[1], c[2]).cast<float>().cwiseMax(0.0f).cwiseMin(1.0f);
    }
    o.mesh_world =
        load_mesh((dir / "truth" / yaml::get_string(objs[i], "mesh", "", file, ctx)).string());
    out.push_back(std::move(o));
  }
  return out;
}

}  // namespace sonar3d
