// The CAD-model catalogue of recognition (thesis sec. 6.3): YAML parsing and mesh loading.
#include "sonar3d/recog/catalogue.hpp"

#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <set>

#include "sonar3d/core/enum_names.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/reference_objects.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/io/yaml_config.hpp"

namespace sonar3d {

namespace fs = std::filesystem;

namespace {
constexpr const char* kSymmetryNames[] = {"none", "180", "full"};  // by Symmetry
}  // namespace

const char* symmetry_name(Symmetry s) { return enum_name(kSymmetryNames, s); }

Catalogue read_catalogue(const std::string& path) {
  const YAML::Node root = yaml::load_file(path);
  if (!root || root.IsNull()) {
    throw Error(path + ": the catalogue is empty: list the CAD models under 'models:'");
  }
  yaml::check_keys(root, {"models"}, path);
  const YAML::Node list = root["models"];
  if (!list || !list.IsSequence() || list.size() == 0) {
    throw Error(yaml::where(path, list ? list : root, "models") +
                ": the catalogue is empty: 'models' must list at least one CAD model");
  }
  if (list.size() > static_cast<std::size_t>(kMaxCatalogueModels)) {
    throw Error(yaml::where(path, list, "models") + ": " + std::to_string(list.size()) +
                " models; a catalogue holds at most " + std::to_string(kMaxCatalogueModels));
  }
  Catalogue cat;
  cat.path = path;
  const fs::path base = fs::path(path).parent_path();
  std::set<std::string> names;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const YAML::Node m = list[i];
    const std::string ctx = "models[" + std::to_string(i) + "]";
    yaml::check_keys(m,
                     {"name", "mesh", "reference", "symmetry", "expected", "scale", "scale_range"},
                     path, ctx);
    CatalogueModel model;
    model.line = m.Mark().line + 1;
    model.name = yaml::get_string(m, "name", "", path, ctx);
    if (model.name.empty()) {
      throw Error(yaml::where(path, m, ctx + ".name") + ": required key is missing or empty");
    }
    if (!names.insert(model.name).second) {
      throw Error(yaml::where(path, m["name"], ctx + ".name") + ": duplicate model name '" +
                  printable(model.name) + "'; give each model its own name");
    }
    const bool has_mesh = static_cast<bool>(m["mesh"]), has_ref = static_cast<bool>(m["reference"]);
    if (has_mesh == has_ref) {
      throw Error(yaml::where(path, m, ctx) +
                  ": give exactly one of 'mesh' (a CAD file) or 'reference' (sphere, tank, "
                  "pillar, riser)");
    }
    if (has_mesh) {
      fs::path mp = yaml::get_string(m, "mesh", "", path, ctx);
      if (mp.empty()) throw Error(yaml::where(path, m["mesh"], ctx + ".mesh") + ": empty path");
      if (mp.is_relative()) mp = base / mp;
      model.mesh_path = mp.string();
    } else {
      model.reference = yaml::get_string(m, "reference", "", path, ctx);
      const auto known = reference_object_names();
      bool ok = false;
      std::string list_names;
      for (const auto& n : known) {
        ok = ok || n == model.reference;
        list_names += (list_names.empty() ? "" : ", ") + n;
      }
      if (!ok) {
        throw Error(yaml::where(path, m["reference"], ctx + ".reference") + ": unknown '" +
                    printable(model.reference) + "' (expected one of: " + list_names + ")");
      }
    }
    const std::string sym = yaml::get_string(m, "symmetry", "none", path, ctx);
    model.symmetry = parse_enum<Symmetry>(
        kSymmetryNames, sym,
        m["symmetry"] ? yaml::where(path, m["symmetry"], ctx + ".symmetry") : "");
    model.expected = yaml::get_int(m, "expected", -1, path, ctx);
    if (m["expected"] && !(model.expected >= 0 && model.expected <= kMaxExpectedInstances)) {
      throw Error(yaml::where(path, m["expected"], ctx + ".expected") + ": must lie in [0, " +
                  std::to_string(kMaxExpectedInstances) + "]");
    }
    model.scale = yaml::get_double(m, "scale", 1.0, path, ctx);
    if (!(model.scale > 1e-3 && model.scale < 1e3)) {
      throw Error(yaml::where(path, m["scale"], ctx + ".scale") + ": must lie in (0.001, 1000)");
    }
    if (m["scale_range"]) {
      // Thesis sec. 6.7 (future work): structures come in sizes off their CAD model's.
      const std::string key = ctx + ".scale_range";
      const std::string at =
          yaml::where(path, m["scale_range"], key) + " (model '" + printable(model.name) + "')";
      std::vector<double> r;
      try {
        r = yaml::get_vector(m, "scale_range", 2, path, ctx);
      } catch (const Error&) {
        throw Error(at + ": expected two finite numbers [min, max], e.g. [0.9, 1.1]");
      }
      if (r[0] > r[1]) {
        throw Error(at + ": scale range inverted (" + fmt::format("{} > {}", r[0], r[1]) +
                    "): give [min, max]");
      }
      if (!(r[0] >= kMinScaleSearch && r[1] <= kMaxScaleSearch)) {
        throw Error(at + ": " + fmt::format("[{}, {}]", r[0], r[1]) + " lies outside [" +
                    fmt::format("{}, {}", kMinScaleSearch, kMaxScaleSearch) +
                    "]: the search refines sizes off by tens of percent; set 'scale' for a "
                    "model of another size");
      }
      if (!(r[0] <= 1 && r[1] >= 1)) {
        throw Error(at + ": " + fmt::format("[{}, {}]", r[0], r[1]) +
                    " must contain 1 (the mesh at its 'scale')");
      }
      model.scale_min = r[0];
      model.scale_max = r[1];
    }
    cat.models.push_back(std::move(model));
  }
  return cat;
}

TriangleMesh load_catalogue_mesh(const Catalogue& catalogue, const CatalogueModel& model) {
  const std::string where_ =
      catalogue.path + ":" + std::to_string(model.line) + ": model '" + printable(model.name) + "'";
  TriangleMesh mesh;
  try {
    mesh = model.reference.empty() ? load_mesh(model.mesh_path)
                                   : make_reference_object(model.reference);
  } catch (const Error& e) {
    throw Error(where_ + ": " + e.what());
  }
  if (mesh.empty()) throw Error(where_ + ": the mesh has no triangles");
  for (auto& v : mesh.vertices) {
    if (!v.allFinite()) throw Error(where_ + ": the mesh has a non-finite vertex");
    v *= static_cast<float>(model.scale);
  }
  if (!(mesh.surface_area() > 0)) throw Error(where_ + ": the mesh has no surface area");
  return mesh;
}

}  // namespace sonar3d
