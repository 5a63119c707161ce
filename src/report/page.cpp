#include "page.hpp"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <fstream>
#include <random>
#include <unordered_map>
#include <utility>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"

namespace fs = std::filesystem;

namespace sonar3d::report_page {

namespace {

std::string read_asset(const fs::path& dir, const fs::path& rel) {
  const fs::path p = dir / rel;
  if (!fs::is_regular_file(p)) {
    throw Error("report: web asset '" + p.string() +
                "' not found: run scripts/install-deps.sh (it runs `npm ci` in web/), or point "
                "--web-dir / SONAR3D_WEB_DIR at a web directory that holds it");
  }
  return read_text_file(p.string());
}

void replace_all(std::string& s, const std::string& from, const std::string& to) {
  for (std::size_t pos = s.find(from); pos != std::string::npos; pos = s.find(from, pos)) {
    s.replace(pos, from.size(), to);
    pos += to.size();
  }
}

// A script inlined in <script>...</script> must not contain "</script" (it would end the
// element) nor "<!--" (it changes how the HTML parser reads script text). Both only occur in
// strings, comments or regular expressions, where "<\/" and "<\!" mean the same.
std::string script_safe(std::string js) {
  replace_all(js, "</script", "<\\/script");
  replace_all(js, "</SCRIPT", "<\\/SCRIPT");
  replace_all(js, "<!--", "<\\!--");
  return js;
}

std::string html_escape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

}  // namespace

WebAssets load_web_assets(const fs::path& dir, const std::string& app_name, bool with_plotly) {
  WebAssets a;
  a.dir = dir;
  a.template_html = read_asset(dir, "report_template.html");
  a.css = read_asset(dir, "report.css");
  a.common_js = read_asset(dir, "common.js");
  a.app_js = read_asset(dir, app_name);
  if (with_plotly) {
    a.plotly_js = read_asset(dir, "node_modules/plotly.js-basic-dist-min/plotly-basic.min.js");
  }
  a.three_js = read_asset(dir, "dist/three-bundle.js");
  return a;
}

std::string base64(const void* data, std::size_t n) {
  static const char* tbl = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  const auto* b = static_cast<const unsigned char*>(data);
  std::string out;
  out.reserve((n + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < n; i += 3) {
    const unsigned v = (b[i] << 16) | (b[i + 1] << 8) | b[i + 2];
    out += tbl[(v >> 18) & 63];
    out += tbl[(v >> 12) & 63];
    out += tbl[(v >> 6) & 63];
    out += tbl[v & 63];
  }
  if (i < n) {
    unsigned v = b[i] << 16;
    if (i + 1 < n) v |= b[i + 1] << 8;
    out += tbl[(v >> 18) & 63];
    out += tbl[(v >> 12) & 63];
    out += (i + 1 < n) ? tbl[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

TriangleMesh simplify_for_display(const TriangleMesh& mesh, std::size_t max_tris,
                                  std::vector<std::array<std::uint8_t, 3>>* colors) {
  if (mesh.triangles.size() <= max_tris) return mesh;
  const bool with_colors = colors != nullptr && colors->size() == mesh.vertices.size();
  const Eigen::AlignedBox3f box = mesh.bounding_box();
  const Eigen::Vector3f lo = box.min();
  const double diag = std::max<double>(box.diagonal().norm(), 1e-9);
  double cell = diag / std::sqrt(static_cast<double>(max_tris));
  for (int attempt = 0; attempt < 40; ++attempt, cell *= 1.3) {
    std::unordered_map<std::uint64_t, int> index;
    std::vector<Eigen::Vector3d> sums, color_sums;
    std::vector<int> counts;
    std::vector<int> remap(mesh.vertices.size());
    for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
      const Eigen::Vector3f q = ((mesh.vertices[v] - lo).cast<double>() / cell).cast<float>();
      const auto ix = static_cast<std::uint64_t>(std::max(0.f, q.x())) & 0x1fffff;
      const auto iy = static_cast<std::uint64_t>(std::max(0.f, q.y())) & 0x1fffff;
      const auto iz = static_cast<std::uint64_t>(std::max(0.f, q.z())) & 0x1fffff;
      const std::uint64_t key = (ix << 42) | (iy << 21) | iz;
      auto [it, inserted] = index.emplace(key, static_cast<int>(sums.size()));
      if (inserted) {
        sums.emplace_back(Eigen::Vector3d::Zero());
        color_sums.emplace_back(Eigen::Vector3d::Zero());
        counts.push_back(0);
      }
      sums[it->second] += mesh.vertices[v].cast<double>();
      if (with_colors) {
        const auto& c = (*colors)[v];
        color_sums[it->second] += Eigen::Vector3d(c[0], c[1], c[2]);
      }
      counts[it->second] += 1;
      remap[v] = it->second;
    }
    TriangleMesh out;
    for (const auto& t : mesh.triangles) {
      const Eigen::Vector3i r(remap[t[0]], remap[t[1]], remap[t[2]]);
      if (r[0] != r[1] && r[1] != r[2] && r[0] != r[2]) out.triangles.push_back(r);
    }
    if (out.triangles.size() > max_tris) continue;
    out.vertices.resize(sums.size());
    for (std::size_t c = 0; c < sums.size(); ++c) {
      out.vertices[c] = (sums[c] / counts[c]).cast<float>();
    }
    if (with_colors) {
      colors->assign(sums.size(), {0, 0, 0});
      for (std::size_t c = 0; c < sums.size(); ++c) {
        const Eigen::Vector3d m = color_sums[c] / counts[c];
        for (int k = 0; k < 3; ++k) (*colors)[c][k] = static_cast<std::uint8_t>(std::lround(m[k]));
      }
    }
    return out;
  }
  return mesh;  // unreachable for finite meshes: the last grid has one cell
}

std::uint64_t fnv1a(const std::string& s) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : s) h = (h ^ c) * 1099511628211ull;
  return h;
}

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M UTC", &tm);
  return buf;
}

std::vector<std::uint32_t> subsample(const PointCloud& cloud, std::size_t budget,
                                     std::uint64_t seed, std::size_t* num_finite) {
  std::vector<std::uint32_t> idx;
  idx.reserve(cloud.size());
  for (std::size_t k = 0; k < cloud.size(); ++k) {
    if (cloud.points[k].allFinite()) idx.push_back(static_cast<std::uint32_t>(k));
  }
  if (num_finite != nullptr) *num_finite = idx.size();
  if (idx.size() > budget) {
    std::mt19937_64 rng(seed);
    for (std::size_t k = 0; k < budget; ++k) {
      std::uniform_int_distribution<std::size_t> pick(k, idx.size() - 1);
      std::swap(idx[k], idx[pick(rng)]);
    }
    idx.resize(budget);
    std::sort(idx.begin(), idx.end());
  }
  return idx;
}

void check_replaceable(const fs::path& output) {
  std::error_code ec;
  if (!fs::exists(output, ec)) return;
  std::string head(256, '\0');
  if (fs::is_regular_file(output, ec)) {
    std::ifstream f(output, std::ios::binary);
    f.read(head.data(), static_cast<std::streamsize>(head.size()));
    head.resize(static_cast<std::size_t>(f.gcount()));
    // Every page opens with its template's comment (web/report_template.html).
    if (head.find("<!-- sonar3d ") != std::string::npos) return;
  }
  throw Error("report: '" + output.string() +
              "' exists and is not a page sonar3d report wrote: remove it or choose another -o");
}

std::string fill_page(const WebAssets& assets, const std::string& title, std::string data_json) {
  // JSON inside <script type="application/json">: '<' only occurs inside JSON strings, where
  // \u003c means the same, so no "</script>" or "<!--" can end or confuse the element.
  replace_all(data_json, "<", "\\u003c");
  // Each placeholder must appear exactly once; positions are found in the template itself so
  // inserted text can never be taken for a placeholder.
  const std::string& tpl = assets.template_html;
  const std::vector<std::pair<std::string, std::string>> parts = {
      {"{{TITLE}}", html_escape(title)},
      {"/*{{STYLE}}*/", assets.css},
      {"<!--{{LIBS}}-->",
       (assets.plotly_js.empty() ? ""
                                 : "<script>\n" + script_safe(assets.plotly_js) + "\n</script>\n") +
           "<script>\n" + script_safe(assets.three_js) + "\n</script>"},
      {"<!--{{DATA}}-->",
       "<script type=\"application/json\" id=\"sonar3d-data\">" + data_json + "</script>"},
      {"<!--{{APP}}-->", "<script>\n" + script_safe(assets.common_js) + "\n</script>\n<script>\n" +
                             script_safe(assets.app_js) + "\n</script>"}};
  std::vector<std::pair<std::size_t, std::size_t>> at;  // (position in tpl, part index)
  for (std::size_t k = 0; k < parts.size(); ++k) {
    const std::string& ph = parts[k].first;
    const std::size_t pos = tpl.find(ph);
    if (pos == std::string::npos || tpl.find(ph, pos + 1) != std::string::npos) {
      throw Error("report: web asset '" + (assets.dir / "report_template.html").string() +
                  "' must contain " + ph + " exactly once");
    }
    at.emplace_back(pos, k);
  }
  std::sort(at.begin(), at.end());
  std::string html;
  std::size_t reserve = tpl.size();
  for (const auto& part : parts) reserve += part.second.size();
  html.reserve(reserve);
  std::size_t cursor = 0;
  for (const auto& [pos, k] : at) {
    html.append(tpl, cursor, pos - cursor);
    html += parts[k].second;
    cursor = pos + parts[k].first.size();
  }
  html.append(tpl, cursor, std::string::npos);
  return html;
}

}  // namespace sonar3d::report_page
