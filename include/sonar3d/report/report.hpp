#pragma once
// `sonar3d report DIR`: one self-contained HTML page for a planner sweep directory (thesis sec.
// 5.7.3): metric-versus-parameter plots like Fig. 4.14–4.20, a sortable results table, and a 3D
// viewer of each reconstructed cloud coloured by its distance to the CAD model (or by height)
// over the semi-transparent model. The JavaScript libraries (Plotly, three.js) are read from the
// web assets directory (web/, filled by `npm ci` in scripts/install-deps.sh) and inlined, so the
// page opens offline and fetches nothing. Directory layout and results.json: docs/report.md.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace sonar3d {

enum class ReportColor { Error, Height };

// Parses "error" | "height"; throws Error listing the names.
ReportColor parse_report_color(const std::string& name);

struct ReportConfig {
  std::filesystem::path output;  // empty: <plan_dir>/report.html
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
  std::string title;              // empty: "sonar3d sweep: <directory name>"
  unsigned long long seed = 1;    // subsampling seed
  bool progress = false;          // progress bar on a terminal (stderr)
  void validate() const;          // throws Error naming the field
};

struct ReportSummary {
  std::filesystem::path output;
  std::size_t num_points = 0;  // configurations in results.json
  std::size_t num_ok = 0;
  std::size_t num_failed = 0;
  std::size_t num_clouds = 0;        // clouds embedded in the viewer
  std::size_t num_cloud_points = 0;  // points embedded over all clouds
  std::uintmax_t bytes = 0;          // size of the page
  // Problems that did not stop the report: an ok point whose cloud file is missing or unreadable
  // is listed in the table without a cloud; a missing truth mesh shows the cloud by height only.
  std::vector<std::string> warnings;
};

// $SONAR3D_WEB_DIR if set; else, for an installed sonar3d, <prefix>/share/sonar3d/web found from
// the executable (/proc/self/exe is <prefix>/bin/...); else the source tree's web/ (a build that
// is not installed).
std::filesystem::path default_web_dir();

// Writes the report of the sweep in `plan_dir` atomically. Throws Error on a missing or malformed
// results.json (naming the file and what is wrong), on missing web assets (saying to run
// scripts/install-deps.sh) and on an invalid config.
ReportSummary write_report(const std::filesystem::path& plan_dir, const ReportConfig& cfg);

}  // namespace sonar3d
