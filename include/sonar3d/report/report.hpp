#pragma once
// `sonar3d report INPUT`: one self-contained HTML page. INPUT is recognised by its content:
//   - a planner sweep directory (results.json; thesis sec. 5.7.3): metric-versus-parameter plots
//     like Fig. 4.14–4.20, a sortable results table, and a 3D viewer of each reconstructed cloud
//     coloured by its distance to the CAD model (or by height) over the semi-transparent model;
//   - a map directory of `sonar3d map` (merged.ply), optionally with the placements of
//     `sonar3d recognize` drawn over it (thesis sec. 6.3);
//   - a world model directory of `sonar3d world` (graph.json; sec. 6.3.3, Fig. 6.18);
//   - a change directory of `sonar3d diff` (changes.json);
//   - a PLY cloud or mesh, e.g. a textured output of `sonar3d texture` (sec. 6.4), in its colours.
// The JavaScript libraries (Plotly, three.js) are read from the web assets directory (web/,
// filled by `npm ci` in scripts/install-deps.sh) and inlined, so the page opens offline and
// fetches nothing. Inputs and layouts: docs/report.md.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "sonar3d/core/params.hpp"

namespace sonar3d {

enum class ReportColor { Error, Height };
inline constexpr const char* kReportColorNames[] = {"error", "height"};

// Parses "error" | "height"; throws Error listing the names.
ReportColor parse_report_color(const std::string& name);

// What `sonar3d report` was given, recognised by content (detect_report_input).
enum class ReportInput { Sweep, Map, World, Changes, Ply };
const char* report_input_name(ReportInput kind);  // "sweep", "map", "world", "changes", "ply"

// A directory holding results.json is a sweep, graph.json a world model, changes.json a change
// directory, merged.ply a map; a regular file must be a PLY (by its magic line). Anything else
// is an Error naming the path and listing what is expected.
ReportInput detect_report_input(const std::filesystem::path& input);

struct ReportConfig {
  std::filesystem::path output;  // empty: <dir>/report.html, or FILE.html beside a PLY
  // Map (or PLY cloud) input: placements.json of `sonar3d recognize` and the catalogue naming
  // its models' meshes (default: the catalogue the placements name, when that file exists).
  // Change input: a catalogue draws the objects' models before and after, not only markers.
  std::filesystem::path placements, catalogue;
  // Further PLY clouds or meshes drawn in every 3D scene page (e.g. `sonar3d texture` outputs).
  std::vector<std::filesystem::path> overlays;
  // Clouds larger than this are shown as a uniform random subsample (seeded: same bytes out).
  std::size_t max_points_per_cloud = 60000;
  // Budget over all clouds of the page, shared evenly, so a 200-point sweep stays a page a
  // browser opens (16 bytes a point before base64).
  std::size_t max_points_total = 1000000;
  // CAD meshes above this many triangles are simplified for display only (vertex clustering);
  // errors are always measured on the full mesh.
  std::size_t max_mesh_triangles = 200000;
  ReportColor color = ReportColor::Error;  // initial colouring of the viewer
  // m, top of the error colour scale; 0: per cloud, its 95th percentile rounded up to 1-2-5
  // (the page also lets the viewer choose it).
  double error_color_max = 0;
  std::filesystem::path web_dir;  // empty: default_web_dir()
  std::string title;              // empty: "sonar3d <kind>: <input name>"
  unsigned long long seed = 1;    // subsampling seed
  bool progress = false;          // progress bar on a terminal (stderr)
  void validate() const;          // throws Error naming the field
};

// The one declaration of the page's settings (core/params.hpp): sonar3d report's flags and its
// --print-config keys, the survey's `report:` block. The keys are the flags' names (as the
// survey's report block always had them). What the page is made of (input, output, placements,
// catalogue, overlays), where the web assets are and the progress bar are the caller's.
template <class V>
void describe(ReportConfig& c, V& v) {
  using params::param;
  v.field(c.max_points_per_cloud, param("max_points", "",
                                        "at most this many points shown per cloud (uniform random "
                                        "subsample, seeded)")
                                      .at_least(1)
                                      .flag("--max-points"));
  v.field(c.max_points_total, param("max_total_points", "",
                                    "budget of points over all clouds of the page, shared "
                                    "evenly")
                                  .at_least(1)
                                  .flag("--max-total-points"));
  v.field(c.max_mesh_triangles,
          param("max_mesh_triangles", "",
                "CAD meshes above this are simplified for display (errors use the full mesh)")
              .at_least(100)
              .flag("--max-mesh-triangles"));
  v.field(c.color, param("color", "", "initial point colouring: distance to CAD, or height")
                       .choices(kReportColorNames)
                       .flag("--color"));
  v.field(
      c.error_color_max,
      param("error_max", "m", "top of the error colour scale (0: per cloud, its 95th percentile)")
          .non_negative()
          .flag("--error-max"));
  v.field(c.title,
          param("title", "", "page title (empty: sonar3d <kind>: <input name>)").flag("--title"));
  v.field(c.seed, param("seed", "", "subsampling seed").flag("--seed"));
}

struct ReportSummary {
  std::filesystem::path output;
  ReportInput input = ReportInput::Sweep;
  std::size_t num_points = 0;  // configurations in results.json
  std::size_t num_ok = 0;
  std::size_t num_failed = 0;
  std::size_t num_clouds = 0;        // clouds embedded in the viewer
  std::size_t num_cloud_points = 0;  // points embedded over all clouds
  std::uintmax_t bytes = 0;          // size of the page
  // Scene pages (map, world, changes, PLY): 3D layers drawn, meshes' triangles shown, table rows.
  std::size_t num_layers = 0;
  std::size_t num_mesh_triangles = 0;
  std::size_t num_table_rows = 0;
  // Problems that did not stop the report: an ok point whose cloud file is missing or unreadable
  // is listed in the table without a cloud; a missing truth mesh shows the cloud by height only.
  std::vector<std::string> warnings;
};

// $SONAR3D_WEB_DIR if set; else, for an installed sonar3d, <prefix>/share/sonar3d/web found from
// the executable (/proc/self/exe is <prefix>/bin/...); else the source tree's web/ (a build that
// is not installed).
std::filesystem::path default_web_dir();

// Writes the report of `input` (any ReportInput) atomically. Throws Error on an input of no known
// kind, on a missing or malformed file of the input (results.json, graph.json, changes.json,
// placements.json, a PLY; naming the file and what is wrong), on missing web assets (saying to
// run scripts/install-deps.sh) and on an invalid config.
ReportSummary write_report(const std::filesystem::path& input, const ReportConfig& cfg);

}  // namespace sonar3d
