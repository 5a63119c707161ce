// Whole workflows (pipeline/survey_pipeline.hpp): sonar3d.survey(), the same library call as
// `sonar3d survey`.
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "common.hpp"
#include "sonar3d/io/params_yaml.hpp"
#include "sonar3d/pipeline/survey_pipeline.hpp"

namespace sonar3d::python {

using namespace pybind11::literals;
namespace fs = std::filesystem;

namespace {

// A YAML node as Python values: maps, lists, and plain scalars as None, bools or numbers (quoted
// scalars stay strings).
py::object from_yaml(const YAML::Node& n) {
  if (n.IsMap()) {
    py::dict d;
    for (const auto& kv : n) d[py::str(kv.first.Scalar())] = from_yaml(kv.second);
    return d;
  }
  if (n.IsSequence()) {
    py::list l;
    for (const auto& e : n) l.append(from_yaml(e));
    return l;
  }
  if (n.IsNull()) return py::none();
  const std::string& s = n.Scalar();
  if (n.Tag() == "?") {  // plain
    if (s == "~" || s == "null") return py::none();
    if (s == "true" || s == "false") return py::bool_(s == "true");
    long long i = 0;
    if (YAML::convert<long long>::decode(n, i)) return py::int_(i);
    double d = 0;
    if (YAML::convert<double>::decode(n, d)) return py::float_(d);
  }
  return py::str(s);
}

// A stage's configuration class as its block, exactly as --print-config writes it (a region as
// six numbers, enums by name); nullopt when `o` is none of Cs.
template <class... Cs>
std::optional<py::object> stage_block(const py::object& o) {
  std::optional<py::object> out;
  const auto one = [&](auto tag) {
    using C = typename decltype(tag)::type;
    if (out || !py::isinstance<C>(o)) return;
    YAML::Emitter e;
    params::emit_yaml(e, o.cast<const C&>());
    out = from_yaml(YAML::Load(e.c_str()));
  };
  (one(std::common_type<Cs>{}), ...);
  return out;
}

// A configuration given as a dict: written as JSON (which is YAML) to a temporary file and read
// by the same strict reader as a --config file, so its errors name the same keys. A block may be
// the stage's configuration class ({'import': {'aris': sonar3d.ArisImportConfig(...)}, 'map':
// sonar3d.MapSurveyConfig(...)}): written as its to_dict().
SurveyConfig config_from_object(const py::object& config, fs::path* file) {
  if (config.is_none()) return {};
  if (py::isinstance<py::dict>(config)) {
    const py::cpp_function as_json([](const py::object& o) -> py::object {
      if (auto block = stage_block<ArisImportConfig, RosbagImportConfig, OculusImportConfig,
                                   HoloOceanImportConfig, MapSurveyConfig, RecognizeConfig,
                                   WorldModelConfig>(o)) {
        return *block;
      }
      if (py::hasattr(o, "tolist")) return o.attr("tolist")();  // numpy arrays (regions)
      if (py::isinstance<py::tuple>(o)) return py::list(o);
      throw py::type_error("survey config: a " +
                           py::type::of(o).attr("__name__").cast<std::string>() +
                           " is no configuration value");
    });
    const std::string text = py::module_::import("json")
                                 .attr("dumps")(config, "default"_a = as_json)
                                 .cast<std::string>();
    static int counter = 0;
    const fs::path tmp =
        fs::temp_directory_path() / ("sonar3d-survey-config-" + std::to_string(::getpid()) + "-" +
                                     std::to_string(counter++) + ".yaml");
    { std::ofstream(tmp) << text << "\n"; }
    try {
      // Relative paths in a dict: from the working directory, as Python's own open() takes them.
      SurveyConfig c = load_survey_config(tmp.string(), fs::current_path());
      fs::remove(tmp);
      return c;
    } catch (...) {
      std::error_code ec;
      fs::remove(tmp, ec);
      throw;
    }
  }
  *file = config.cast<fs::path>();
  return load_survey_config(file->string());
}

}  // namespace

void bind_pipeline(py::module_& m) {
  m.def(
      "survey",
      [](const fs::path& input, const fs::path& output, const std::optional<fs::path>& catalogue,
         const py::object& config, const py::object& progress) {
        SurveyOptions o;
        o.input = input;
        o.output = output;
        if (catalogue) o.catalogue = *catalogue;
        o.config = config_from_object(config, &o.config_file);
        ProgressArg p(progress);
        o.progress = p.terminal();
        std::vector<std::string> warnings;
        o.on_warning = [&warnings](const std::string& w) { warnings.push_back(w); };
        const SurveyResult r = p.run([&] { return run_survey(o); });
        py::dict summary = json_loads(r.summary_json);
        summary["warnings"] = warnings;
        return summary;
      },
      "input"_a, "output"_a, "catalogue"_a = py::none(), "config"_a = py::none(),
      "progress"_a = py::none(),
      "Runs (or resumes) a whole survey, as `sonar3d survey` does: import (an ARIS file, ROS 1/2 "
      "bag, HoloOcean recording or Oculus stream; a dataset directory is used in place) -> map -> "
      "recognize (with `catalogue`, a catalogue YAML) -> world model -> texture (when the dataset "
      "has camera frames) -> report, into the directory `output` (new, empty, or an earlier "
      "survey's, which is resumed: unchanged stages are skipped). `config`: a survey YAML path, "
      "or a dict of the same shape ({'import': {'aris': {'navigation': 'nav.csv'}}, 'map': "
      "{'cell_m': 0.05}, 'recognize': {...}}: each block as its command's --print-config prints "
      "it; a block may be the stage's configuration class: {'import': {'aris': "
      "sonar3d.ArisImportConfig(vertical_aperture_deg=10)}, 'map': sonar3d.MapSurveyConfig(...)}; "
      "docs/survey.md). `progress`: None, True (terminal bars) or a callable "
      "progress(done, total) called for each stage and each of its steps. Returns the summary as "
      "a dict (output/summary.json: per stage its status, seconds, peak_memory_mb and figures) "
      "plus 'warnings'. Raises sonar3d.Error('survey: stage NAME failed: ...') on failure, the "
      "finished stages left in place.");
  m.def(
      "survey_config",
      [](const py::object& config) {
        fs::path file;
        return survey_config_yaml(config_from_object(config, &file));
      },
      "config"_a = py::none(),
      "The whole effective survey configuration as YAML text (`sonar3d survey --print-config`): "
      "every option of every stage, defaults included; `config` as for survey().");
}

}  // namespace sonar3d::python
