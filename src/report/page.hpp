#pragma once
// Internal to src/report: what every page `sonar3d report` writes shares — the web assets, the
// template filling, base64 of binary arrays, display-only mesh simplification and seeded cloud
// subsampling (docs/report.md, "How the page stays offline").
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "sonar3d/core/mesh.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/report/report.hpp"

namespace sonar3d::report_page {

// The files a page is made of: the page's own template, style and code (committed in web/) and
// the libraries from npm (`npm ci` in web/ builds dist/three-bundle.js).
struct WebAssets {
  std::filesystem::path dir;
  std::string template_html, css, common_js, app_js, plotly_js, three_js;
};

// Reads web/report_template.html (every page's), web/<app_name> and the shared files (Plotly only
// when asked: the scene pages draw no plot); a missing one is an Error saying to run
// scripts/install-deps.sh.
WebAssets load_web_assets(const std::filesystem::path& dir, const std::string& app_name,
                          bool with_plotly);

std::string base64(const void* data, std::size_t n);

// Display-only simplification of a large mesh by vertex clustering on a grid: each occupied cell
// keeps the mean of its vertices (and of their colours when `colors` holds one per vertex; it is
// replaced by the clustered colours), triangles that collapse are dropped. The cell grows until
// the mesh has at most `max_tris` triangles.
TriangleMesh simplify_for_display(const TriangleMesh& mesh, std::size_t max_tris,
                                  std::vector<std::array<std::uint8_t, 3>>* colors = nullptr);

std::uint64_t fnv1a(const std::string& s);
std::string utc_now();

// Indices of at most `budget` finite points of `cloud`: all of them when they fit, else a uniform
// random subset (partial Fisher-Yates seeded by `seed`), in increasing order. `num_finite` gets
// the number of finite points.
std::vector<std::uint32_t> subsample(const PointCloud& cloud, std::size_t budget,
                                     std::uint64_t seed, std::size_t* num_finite);

// Throws Error unless `output` is absent or a page sonar3d report wrote (its template's opening
// comment): the report never replaces a file it did not write.
void check_replaceable(const std::filesystem::path& output);

// The page: the template with its placeholders ({{TITLE}}, /*{{STYLE}}*/, <!--{{LIBS}}-->,
// <!--{{DATA}}-->, <!--{{APP}}-->) replaced by the escaped title, the style, the inlined
// libraries, `data_json` in <script type="application/json" id="sonar3d-data"> and the code.
std::string fill_page(const WebAssets& assets, const std::string& title, std::string data_json);

// A top view of the navigation before and after drift correction (x East, y North, metres), as
// SVG: equal scale on both axes, axes ticked and labelled in metres, a scale bar, a north arrow
// and a legend (src/report/track_figure.cpp).
std::string track_svg(const std::vector<Eigen::Vector2d>& before,
                      const std::vector<Eigen::Vector2d>& after);

// The 3D scene page of a map, world, change directory or PLY file (src/report/scene_report.cpp).
ReportSummary write_scene_report(const std::filesystem::path& input, ReportInput kind,
                                 const ReportConfig& cfg);

}  // namespace sonar3d::report_page
