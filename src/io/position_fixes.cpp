// Absolute position fixes (USBL/GNSS) from CSV or TUM: io/position_fixes.hpp.
#include "sonar3d/io/position_fixes.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "text_fields.hpp"

namespace fs = std::filesystem;

namespace sonar3d {
namespace {

using text::lower;
using text::trim;

std::string fmt_num(double v) {
  std::ostringstream os;
  os << std::setprecision(10) << v;
  return os.str();
}

// One field: a finite number, else "<where>: column '<what>' (field k) '...' is not a number".
double number(const std::string& cell, const std::string& where, const std::string& what,
              int field) {
  return text::parse_number(cell, where,
                            "column '" + what + "' (field " + std::to_string(field) + ")");
}

void check_fix(const PositionFix& f, const std::vector<PositionFix>& out, const std::string& where,
               const std::string& sigma_col) {
  for (int k = 0; k < 3; ++k) {
    if (std::abs(f.p[k]) > limits::kMaxCoordinate) {
      throw Error(where + ": coordinate " + fmt_num(f.p[k]) + " m is beyond ±" +
                  fmt_num(limits::kMaxCoordinate) + " m: fixes must be in the local ENU world " +
                  "frame of the navigation, in metres");
    }
  }
  if (!(f.sigma_m > 0) || f.sigma_m > kMaxFixSigma) {
    throw Error(where + ": " + sigma_col + " " + fmt_num(f.sigma_m) + " m must lie in (0, " +
                fmt_num(kMaxFixSigma) + "] m");
  }
  if (!out.empty() && !(f.time > out.back().time)) {
    throw Error(where + ": time " + fmt_num(f.time) + " s " +
                (f.time == out.back().time ? "repeats" : "goes back from") + " the fix of line " +
                std::to_string(out.back().line) + " (" + fmt_num(out.back().time) +
                " s): fix times must strictly increase");
  }
  if (out.size() >= kMaxFixes) {
    throw Error(where + ": more than " + std::to_string(kMaxFixes) + " fixes");
  }
}

}  // namespace

std::vector<PositionFix> parse_position_fixes(const std::string& text, const std::string& name,
                                              FixFormat format, double tum_sigma_m) {
  if (text.size() > kMaxFixFileBytes) {
    throw Error(name + ": " + std::to_string(text.size()) + " bytes: a fixes file is at most " +
                std::to_string(kMaxFixFileBytes >> 20) + " MiB");
  }
  if (format == FixFormat::Auto) {
    const std::string ext = lower(fs::path(name).extension().string());
    format = (ext == ".tum" || ext == ".txt") ? FixFormat::Tum : FixFormat::Csv;
  }
  if (format == FixFormat::Tum && !(tum_sigma_m > 0 && tum_sigma_m <= kMaxFixSigma)) {
    throw Error(name + ": TUM fixes carry no σ: give one for all (--fix-sigma, metres, in (0, " +
                fmt_num(kMaxFixSigma) + "])");
  }
  std::vector<PositionFix> out;
  std::istringstream is(text);
  std::string line;
  int lineno = 0;
  // CSV columns: time, x, y, z (optional), sigma.
  int c_t = -1, c_x = -1, c_y = -1, c_z = -1, c_s = -1;
  std::vector<std::string> header;
  bool have_header = false;
  while (std::getline(is, line)) {
    ++lineno;
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    const std::string where = name + ":" + std::to_string(lineno);
    PositionFix f;
    f.line = lineno;
    if (format == FixFormat::Tum) {
      std::istringstream ls(t);
      std::vector<std::string> cells;
      std::string c;
      while (ls >> c && cells.size() <= 8) cells.push_back(c);
      if (cells.size() != 8) {
        throw Error(where + ": expected 8 fields 't x y z qx qy qz qw' (TUM), got " +
                    (cells.size() > 8 ? std::string("more") : std::to_string(cells.size())));
      }
      static const char* kTum[] = {"t", "x", "y", "z", "qx", "qy", "qz", "qw"};
      double v[8];
      for (int k = 0; k < 8; ++k) v[k] = number(cells[k], where, kTum[k], k + 1);
      f.time = v[0];
      f.p = {v[1], v[2], v[3]};
      f.has_z = true;
      f.sigma_m = tum_sigma_m;
      check_fix(f, out, where, "--fix-sigma");
      out.push_back(f);
      continue;
    }
    std::vector<std::string> cells;
    {
      std::string cell;
      std::istringstream ls(t);
      while (std::getline(ls, cell, ',')) cells.push_back(trim(cell));
      if (t.back() == ',') cells.push_back("");
    }
    if (!have_header) {
      have_header = true;
      header = cells;
      for (std::size_t i = 0; i < cells.size(); ++i) {
        const std::string h = lower(cells[i]);
        const int k = static_cast<int>(i);
        if ((h == "time_s" || h == "time" || h == "t") && c_t < 0) c_t = k;
        if ((h == "x_m" || h == "x") && c_x < 0) c_x = k;
        if ((h == "y_m" || h == "y") && c_y < 0) c_y = k;
        if ((h == "z_m" || h == "z") && c_z < 0) c_z = k;
        if ((h == "sigma_m" || h == "sigma") && c_s < 0) c_s = k;
      }
      if (c_t < 0 || c_x < 0 || c_y < 0 || c_s < 0) {
        throw Error(where + ": expected a header naming the columns time_s, x_m, y_m, sigma_m " +
                    "and optionally z_m (any order), got '" + printable(t) + "'");
      }
      continue;
    }
    const int needed = std::max({c_t, c_x, c_y, c_z, c_s}) + 1;
    if (static_cast<int>(cells.size()) < needed) {
      throw Error(where + ": expected at least " + std::to_string(needed) + " fields, got " +
                  std::to_string(cells.size()));
    }
    auto get = [&](int c) { return number(cells[c], where, header[c], c + 1); };
    f.time = get(c_t);
    f.p.x() = get(c_x);
    f.p.y() = get(c_y);
    if (c_z >= 0) {
      f.p.z() = get(c_z);
      f.has_z = true;
    }
    f.sigma_m = get(c_s);
    check_fix(f, out, where,
              "column '" + header[c_s] + "' (field " + std::to_string(c_s + 1) + "): σ");
    out.push_back(f);
  }
  if (format == FixFormat::Csv && !have_header) {
    throw Error(name + ": empty fixes file (no header 'time_s,x_m,y_m[,z_m],sigma_m')");
  }
  if (out.empty()) throw Error(name + ": the fixes file holds no fix");
  return out;
}

std::vector<PositionFix> read_position_fixes(const std::string& path, FixFormat format,
                                             double tum_sigma_m) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error("cannot open fixes file '" + path + "': no such file");
  if (!fs::is_regular_file(path, ec)) {
    throw Error("cannot read fixes file '" + path + "': not a regular file");
  }
  const auto size = fs::file_size(path, ec);
  if (!ec && size > kMaxFixFileBytes) {
    throw Error(path + ": " + std::to_string(size) + " bytes: a fixes file is at most " +
                std::to_string(kMaxFixFileBytes >> 20) + " MiB");
  }
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error("cannot open fixes file '" + path + "'");
  std::ostringstream ss;
  ss << f.rdbuf();
  return parse_position_fixes(ss.str(), path, format, tum_sigma_m);
}

}  // namespace sonar3d
