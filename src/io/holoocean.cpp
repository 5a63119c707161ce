#include "sonar3d/io/holoocean.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "sonar3d/core/enum_names.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/core/trajectory.hpp"
#include "sonar3d/core/units.hpp"
#include "sonar3d/io/dataset.hpp"

extern char** environ;

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace sonar3d {
namespace {

// ---------------------------------------------------------------- Config.json

std::string json_type(const json& j) { return j.type_name(); }

double get_number(const json& cfg, const std::string& key, const std::string& where) {
  if (!cfg.contains(key)) {
    throw Error(where + ": key '" + key +
                "' is missing (the importer needs RangeBins, AzimuthBins, RangeMin, RangeMax, "
                "Azimuth and Elevation given explicitly)");
  }
  const json& v = cfg.at(key);
  if (!v.is_number()) {
    throw Error(where + ": key '" + key + "' must be a number, got " + json_type(v));
  }
  const double d = v.get<double>();
  if (!std::isfinite(d)) throw Error(where + ": key '" + key + "' is not finite");
  return d;
}

int get_count(const json& cfg, const std::string& key, const std::string& where) {
  const double d = get_number(cfg, key, where);
  if (d != std::floor(d) || d < 1 || d > 1e6) {
    throw Error(where + ": key '" + key + "' must be a positive integer, got " +
                cfg.at(key).dump());
  }
  return static_cast<int>(d);
}

std::string string_or(const json& j, const char* key, const std::string& fallback) {
  return j.contains(key) && j.at(key).is_string() ? j.at(key).get<std::string>() : fallback;
}

// ---------------------------------------------------------------- the pickle decoder

// Runs in the child interpreter. Protocol on stdout: one JSON line per message, a frame's raw
// image bytes (C order, native endianness) right after its line. The unpickler only builds numpy
// arrays, dtypes and plain containers: a pickle can run arbitrary code otherwise.
const char* kDecoderScript = R"PY(
import sys, os, json, pickle
out = sys.stdout.buffer
def send(msg, payload=b""):
    out.write(json.dumps(msg).encode("utf-8") + b"\n")
    if payload:
        out.write(payload)
    out.flush()
try:
    import numpy as np
except Exception as e:
    send({"fatal": "numpy cannot be imported by %s (%s: %s)" % (sys.executable, type(e).__name__, e)})
    sys.exit(0)
ALLOWED = {
    ("numpy.core.multiarray", "_reconstruct"), ("numpy.core.multiarray", "scalar"),
    ("numpy.core.numeric", "_frombuffer"), ("numpy", "ndarray"), ("numpy", "dtype"),
    ("collections", "OrderedDict"), ("builtins", "bytearray"), ("_codecs", "encode"),
}
class Refused(Exception):
    pass
class SafeUnpickler(pickle.Unpickler):
    def find_class(self, module, name):
        if module.startswith("numpy._core"):  # pickled by numpy >= 2
            module = "numpy.core" + module[len("numpy._core"):]
        if (module, name) not in ALLOWED:
            raise Refused("it refers to %s.%s; only numpy arrays and plain containers are "
                          "loaded (a pickle can run arbitrary code)" % (ascii(module)[:80],
                                                                         ascii(name)[:80]))
        return super().find_class(module, name)
base, image_key, pose_key, budget = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
# The memory budget: what the interpreter holds now plus `budget` bytes of address space, so a
# tiny pickle that asks for bytearray(3e9) or a huge memo index fails with a MemoryError.
try:
    import resource
    with open("/proc/self/statm") as sf:
        vm = int(sf.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    resource.setrlimit(resource.RLIMIT_AS, (vm + budget, vm + budget))
except (ImportError, OSError, ValueError):
    pass
send({"hello": 1, "numpy": np.__version__})
for name in sys.argv[5:]:
    msg = {"file": name}
    try:
        with open(os.path.join(base, name), "rb") as f:
            d = SafeUnpickler(f).load()
            if f.read(1):
                raise pickle.UnpicklingError("trailing bytes after the pickle")
    except Refused as e:
        msg["error"] = "not loaded: %s" % e
        send(msg)
        continue
    except MemoryError:
        msg["error"] = ("cannot unpickle: it needs more memory than the decoder's budget "
                        "(docs/formats.md, Limits); the file is corrupt or not a HoloOcean frame")
        send(msg)
        continue
    except Exception as e:
        msg["error"] = "cannot unpickle (%s: %s); the file is truncated or corrupt" % (
            type(e).__name__, str(e)[:200])
        send(msg)
        continue
    if not isinstance(d, dict):
        msg["error"] = "holds a %s; expected a dict with '%s' and '%s'" % (
            type(d).__name__, image_key, pose_key)
        send(msg)
        continue
    keys = ", ".join(sorted(repr(k)[:40] for k in d.keys()))[:300]
    payload = b""
    try:
        for key in (image_key, pose_key):
            if key not in d:
                raise ValueError("key '%s' is missing (keys: %s)" % (key, keys))
            if not isinstance(d[key], np.ndarray):
                raise ValueError("'%s' is a %s, expected a numpy array" % (key, type(d[key]).__name__))
        img, pose = d[image_key], d[pose_key]
        msg["dtype"] = str(img.dtype)
        msg["shape"] = list(img.shape)
        msg["pose_dtype"] = str(pose.dtype)
        msg["pose_shape"] = list(pose.shape)
        if pose.shape == (4, 4) and pose.dtype.kind in "fiu":
            if not np.all(np.isfinite(pose)):
                raise ValueError("'%s' holds non-finite values" % pose_key)
            msg["pose"] = [float(v) for v in pose.astype(np.float64).ravel()]
        if img.ndim == 2 and img.dtype.name in ("uint8", "float32"):
            payload = np.ascontiguousarray(img, dtype=img.dtype.newbyteorder("=")).tobytes()
    except Exception as e:
        msg["error"] = str(e)[:300]
        payload = b""
    msg["nbytes"] = len(payload)
    send(msg, payload)
send({"done": len(sys.argv) - 5})
)PY";

// A child interpreter running the decoder, read through a pipe. The destructor stops and reaps it.
class DecoderProcess {
 public:
  DecoderProcess(const std::string& python, const std::vector<std::string>& args) {
    char tmpl[] = "/tmp/sonar3d_pickle_stderr_XXXXXX";
    const int err_fd = mkstemp(tmpl);
    if (err_fd < 0) throw Error("cannot create a temporary file for the pickle decoder");
    stderr_path_ = tmpl;
    int fds[2];
    if (pipe(fds) != 0) {
      close(err_fd);
      throw Error("cannot create a pipe for the pickle decoder");
    }
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
    posix_spawn_file_actions_adddup2(&actions, err_fd, STDERR_FILENO);
    posix_spawn_file_actions_addclose(&actions, fds[0]);
    posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
    std::vector<std::string> argv_s = {python, "-c", kDecoderScript};
    argv_s.insert(argv_s.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& s : argv_s) argv.push_back(s.data());
    argv.push_back(nullptr);
    const int rc = posix_spawnp(&pid_, python.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    close(fds[1]);
    close(err_fd);
    if (rc != 0) {
      close(fds[0]);
      pid_ = -1;
      throw Error("cannot run the Python interpreter '" + python + "' (" + std::strerror(rc) +
                  ") needed to read HoloOcean pickles: install python3 and python3-numpy "
                  "(scripts/install-deps.sh) or name an interpreter with --python");
    }
    in_ = fdopen(fds[0], "rb");
  }

  ~DecoderProcess() {
    if (in_) std::fclose(in_);
    if (pid_ > 0) {
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == 0) {
        kill(pid_, SIGKILL);  // our own child, stopped early because of an error
        waitpid(pid_, &status, 0);
      }
    }
    if (!stderr_path_.empty()) std::remove(stderr_path_.c_str());
  }

  // The next JSON message; throws when the child ends without one.
  json next_message() {
    std::string line;
    int c;
    while ((c = std::fgetc(in_)) != EOF && c != '\n') line.push_back(static_cast<char>(c));
    if (c == EOF) throw Error(died_message());
    try {
      return json::parse(line);
    } catch (const json::exception&) {
      throw Error("the pickle decoder printed something unexpected: '" + line.substr(0, 200) + "'");
    }
  }

  void read_bytes(void* dst, std::size_t n) {
    if (std::fread(dst, 1, n, in_) != n) throw Error(died_message());
  }

  // Waits for a clean exit.
  void finish() {
    if (pid_ <= 0) return;
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
      throw Error("the pickle decoder failed: " + stderr_tail());
    }
  }

 private:
  std::string stderr_tail() const {
    std::ifstream f(stderr_path_);
    std::string s((std::istreambuf_iterator<char>(f)), {});
    while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
    const auto nl = s.rfind('\n');
    if (nl != std::string::npos) s = s.substr(nl + 1);  // the exception line of a traceback
    return s.empty() ? "no message" : s;
  }
  std::string died_message() {
    int status = 0;
    if (pid_ > 0) {
      waitpid(pid_, &status, 0);
      pid_ = -1;
    }
    std::string how = WIFEXITED(status) && WEXITSTATUS(status) == 127
                          ? "the interpreter could not be started"
                          : stderr_tail();
    return "the pickle decoder stopped early (" + how +
           "); check that python3 and python3-numpy are installed";
  }

  pid_t pid_ = -1;
  FILE* in_ = nullptr;
  std::string stderr_path_;
};

// Data/N.pkl files sorted by N.
struct PickleFile {
  long number;
  std::string name;  // relative to Data/
};

std::vector<PickleFile> list_pickles(const fs::path& data_dir) {
  if (!fs::is_directory(data_dir)) {
    throw Error("'" + data_dir.string() +
                "' is missing: a HoloOcean dataset keeps its frames in "
                "Data/N.pkl");
  }
  std::vector<PickleFile> files;
  std::map<long, std::string> seen;
  for (const auto& e : fs::directory_iterator(data_dir)) {
    if (!e.is_regular_file() || e.path().extension() != ".pkl") continue;
    const std::string stem = e.path().stem().string();
    const std::string name = e.path().filename().string();
    if (stem.empty() || stem.size() > 12 ||
        !std::all_of(stem.begin(), stem.end(), [](char c) { return c >= '0' && c <= '9'; })) {
      throw Error((data_dir / name).string() +
                  ": frame files must be named by their number (N.pkl) to give their order");
    }
    const long n = std::stol(stem);
    if (seen.count(n)) {
      throw Error((data_dir / name).string() + ": frame number " + std::to_string(n) +
                  " repeats '" + seen[n] + "'");
    }
    seen[n] = name;
    files.push_back({n, name});
  }
  if (files.empty()) throw Error("'" + data_dir.string() + "' holds no .pkl frame files");
  std::sort(files.begin(), files.end(),
            [](const PickleFile& a, const PickleFile& b) { return a.number < b.number; });
  return files;
}

// The sonar pose of one frame: a rigid transform within `tol`, re-orthonormalised.
Eigen::Isometry3d rigid_pose(const json& values, double tol, const std::string& where) {
  Eigen::Matrix4d M;
  for (int k = 0; k < 16; ++k) M(k / 4, k % 4) = values.at(k).get<double>();
  if (!M.allFinite()) throw Error(where + ": PoseSensor holds non-finite values");
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  const double ortho = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  const double det = R.determinant();
  const double bottom =
      std::max({std::abs(M(3, 0)), std::abs(M(3, 1)), std::abs(M(3, 2)), std::abs(M(3, 3) - 1.0)});
  if (ortho > tol || std::abs(det - 1.0) > tol || bottom > tol) {
    std::ostringstream os;
    os << where << ": PoseSensor is not a rigid transform (max |RᵀR − I| = " << ortho
       << ", det R = " << det << ", last row " << M.row(3) << "); expected a 4×4 sensor-to-world "
       << "pose with a rotation block";
    throw Error(os.str());
  }
  // Nearest rotation (polar decomposition): float32 storage leaves ~1e-7 errors.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = svd.matrixU() * svd.matrixV().transpose();
  T.translation() = M.topRightCorner<3, 1>();
  return T;
}

}  // namespace

const char* holoocean_bins_name(HoloOceanBins b) { return enum_name(kHoloOceanBinsNames, b); }

HoloOceanBins parse_holoocean_bins(const std::string& s) {
  return parse_enum<HoloOceanBins>(kHoloOceanBinsNames, s, "HoloOcean bin convention");
}

void HoloOceanImportConfig::validate() const {
  params::check(*this, "HoloOcean import:");
  if (!std::isfinite(frame_rate_hz) || frame_rate_hz < 0) {
    throw Error("HoloOcean import: 'frame_rate_hz' must be >= 0 (0 = the sensor's Hz)");
  }
  if (!(rigid_tolerance > 0) || !(rigid_tolerance < 0.1)) {
    throw Error("HoloOcean import: 'rigid_tolerance' must lie in (0, 0.1)");
  }
  if (pose_key.empty()) throw Error("HoloOcean import: 'pose_key' must not be empty");
}

HoloOceanSonar read_holoocean_config(const fs::path& config_json, const std::string& sensor) {
  const std::string file = config_json.string();
  std::ifstream f(config_json);
  if (!f) throw Error("cannot open '" + file + "' (a HoloOcean dataset has a Config.json)");
  std::error_code ec;
  const auto size = fs::file_size(config_json, ec);
  if (!ec && size > limits::kMaxConfigBytes) {
    throw Error(file + " is " + std::to_string(size) + " bytes; Config.json is limited to " +
                std::to_string(limits::kMaxConfigBytes) + " bytes");
  }
  // Nesting is bounded while parsing: copying or comparing a value 200,000 levels deep recurses
  // as deep and overflows the stack.
  const json::parser_callback_t depth_guard = [&file](int depth, json::parse_event_t event, json&) {
    if ((event == json::parse_event_t::object_start || event == json::parse_event_t::array_start) &&
        depth >= limits::kMaxNestingDepth) {
      throw Error(file + ": JSON nested more than " + std::to_string(limits::kMaxNestingDepth) +
                  " levels deep");
    }
    return true;
  };
  json root;
  try {
    root = json::parse(f, depth_guard);
  } catch (const json::parse_error& e) {
    throw Error(file + ": malformed JSON at byte " + std::to_string(e.byte) + ": " + e.what());
  } catch (const json::exception& e) {
    // e.g. "number overflow parsing '1e309'"
    throw Error(file + ": malformed JSON: " + e.what());
  }
  if (!root.is_object() || !root.contains("agents") || !root.at("agents").is_array()) {
    throw Error(file + ": expected a HoloOcean scenario with an 'agents' list");
  }
  struct Found {
    std::string agent;
    const json* sonar;
    std::vector<const json*> pose_sensors;
  };
  std::vector<Found> found;
  const json& agents = root.at("agents");
  for (std::size_t a = 0; a < agents.size(); ++a) {
    const json& agent = agents[a];
    if (!agent.is_object() || !agent.contains("sensors") || !agent.at("sensors").is_array()) {
      throw Error(file + ": agents[" + std::to_string(a) + "] has no 'sensors' list");
    }
    std::vector<const json*> sonars, poses;
    for (const json& s : agent.at("sensors")) {
      if (!s.is_object()) continue;
      const std::string type = string_or(s, "sensor_type", "");
      if (type == "ImagingSonar") sonars.push_back(&s);
      if (type == "PoseSensor") poses.push_back(&s);
    }
    for (const json* s : sonars) {
      found.push_back({string_or(agent, "agent_name", "agent" + std::to_string(a)), s, poses});
    }
  }
  std::vector<Found> chosen;
  for (const auto& fd : found) {
    if (sensor.empty() || string_or(*fd.sonar, "sensor_name", "ImagingSonar") == sensor) {
      chosen.push_back(fd);
    }
  }
  if (chosen.empty()) {
    throw Error(file + (sensor.empty() ? ": no sensor of type 'ImagingSonar' in any agent"
                                       : ": no ImagingSonar named '" + sensor + "'"));
  }
  if (chosen.size() > 1) {
    std::string names;
    for (const auto& fd : chosen) {
      names += (names.empty() ? "" : ", ") + fd.agent + "/" +
               string_or(*fd.sonar, "sensor_name", "ImagingSonar");
    }
    throw Error(file + ": several ImagingSonar sensors (" + names +
                "); choose one by its sensor_name (--sensor)");
  }
  const Found& fd = chosen.front();
  const json& s = *fd.sonar;
  HoloOceanSonar out;
  out.agent_name = fd.agent;
  out.sensor_name = string_or(s, "sensor_name", "ImagingSonar");
  const std::string where = file + ": " + fd.agent + "/" + out.sensor_name + ".configuration";
  if (!s.contains("configuration") || !s.at("configuration").is_object()) {
    throw Error(where + " is missing");
  }
  const json& c = s.at("configuration");
  out.range_bins = get_count(c, "RangeBins", where);
  out.azimuth_bins = get_count(c, "AzimuthBins", where);
  out.range_min = get_number(c, "RangeMin", where);
  out.range_max = get_number(c, "RangeMax", where);
  out.azimuth_deg = get_number(c, "Azimuth", where);
  out.elevation_deg = get_number(c, "Elevation", where);
  if (out.range_min < 0 || !(out.range_max > out.range_min)) {
    throw Error(where + ": need 0 <= RangeMin < RangeMax, got RangeMin " +
                std::to_string(out.range_min) + ", RangeMax " + std::to_string(out.range_max));
  }
  if (!(out.azimuth_deg > 0 && out.azimuth_deg < 360)) {
    throw Error(where + ": Azimuth must lie in (0°, 360°), got " + std::to_string(out.azimuth_deg));
  }
  if (!(out.elevation_deg > 0 && out.elevation_deg < 180)) {
    throw Error(where + ": Elevation must lie in (0°, 180°), got " +
                std::to_string(out.elevation_deg));
  }
  if (s.contains("Hz")) {
    if (!s.at("Hz").is_number() || !(s.at("Hz").get<double>() > 0)) {
      throw Error(file + ": " + fd.agent + "/" + out.sensor_name + ".Hz must be a number > 0");
    }
    out.rate_hz = s.at("Hz").get<double>();
  }
  // The poses come from a PoseSensor: they are the sonar's only when it sits where the sonar
  // sits (same socket, location and rotation), as in neusis and AONeuS.
  if (fd.pose_sensors.empty()) {
    out.warnings.push_back(fd.agent + " has no PoseSensor in " + file +
                           "; PoseSensor in the pickles is taken as the sonar pose");
  } else {
    bool mounted_alike = false;
    for (const json* p : fd.pose_sensors) {
      bool same = true;
      for (const char* key : {"socket", "location", "rotation"}) {
        const json a = s.contains(key) ? s.at(key) : json();
        const json b = p->contains(key) ? p->at(key) : json();
        if (a != b) same = false;
      }
      mounted_alike = mounted_alike || same;
    }
    if (!mounted_alike) {
      out.warnings.push_back("the PoseSensor of " + fd.agent +
                             " is not mounted like the ImagingSonar (socket, "
                             "location or rotation differ in " +
                             file + "): its poses may not be the sonar's");
    }
  }
  return out;
}

SonarSpec holoocean_sonar_spec(const HoloOceanSonar& h, HoloOceanBins bins) {
  SonarSpec s;
  s.name = "holoocean-" + h.sensor_name;
  const double dr = (h.range_max - h.range_min) / h.range_bins;
  const double az = h.azimuth_deg * kDeg;
  const double da = az / h.azimuth_bins;
  s.range_bins = h.range_bins;
  if (bins == HoloOceanBins::Sample) {
    // Row i must be centred on RangeMin + iΔr: r_min + (i + ½)Δr = RangeMin + iΔr.
    s.r_min = h.range_min - 0.5 * dr;
    s.r_max = h.range_max - 0.5 * dr;
    if (s.r_min < 0) {
      throw Error("HoloOcean sonar '" + h.sensor_name + "': RangeMin " +
                  std::to_string(h.range_min) + " m is less than half a range bin (" +
                  std::to_string(0.5 * dr) +
                  " m), so the 'sample' convention would put row 0 "
                  "at a negative near edge; import with the 'cell' convention (--bins cell)");
    }
    // Column j at azimuth −A/2 + jΔa; positive azimuth is toward +y (left), as our bearing.
    s.bearings_rad.resize(h.azimuth_bins);
    for (int j = 0; j < h.azimuth_bins; ++j) s.bearings_rad[j] = -0.5 * az + j * da;
  } else {
    s.r_min = h.range_min;
    s.r_max = h.range_max;
    s.set_uniform_bearings(az, h.azimuth_bins);
  }
  s.vertical_aperture_rad = h.elevation_deg * kDeg;
  s.beam_pattern.kind = BeamPattern::Kind::Flat;
  s.T_vehicle_sonar = Eigen::Isometry3d::Identity();
  s.validate();
  return s;
}

std::string pickle_python(const std::string& requested) {
  if (!requested.empty()) return requested;
  if (const char* env = std::getenv("SONAR3D_PYTHON"); env && *env) return env;
  // Debian's interpreter has python3-numpy; a python3 earlier on PATH (pyenv, venv) may not.
  if (access("/usr/bin/python3", X_OK) == 0) return "/usr/bin/python3";
  return "python3";
}

HoloOceanImportResult import_holoocean(const fs::path& dir, const fs::path& out,
                                       const HoloOceanImportConfig& config, bool progress) {
  config.validate();
  if (!fs::is_directory(dir)) throw Error("'" + dir.string() + "' is not a directory");
  HoloOceanImportResult res;
  res.sonar = read_holoocean_config(dir / "Config.json", config.sensor);
  res.warnings = res.sonar.warnings;
  res.spec = holoocean_sonar_spec(res.sonar, config.bins);
  res.frame_rate_hz = config.frame_rate_hz > 0 ? config.frame_rate_hz
                      : res.sonar.rate_hz > 0  ? res.sonar.rate_hz
                                               : 1.0;
  const fs::path data_dir = dir / "Data";
  const std::vector<PickleFile> files = list_pickles(data_dir);
  const std::string image_key = config.image_key.empty() ? res.sonar.sensor_name : config.image_key;

  const std::string python = pickle_python(config.python);
  std::uintmax_t largest = 0;
  for (const auto& pf : files) {
    std::error_code ec;
    const auto sz = fs::file_size(data_dir / pf.name, ec);
    if (!ec) largest = std::max(largest, sz);
  }
  const std::uintmax_t budget = limits::kPickleBudgetBytes + 4 * largest;
  std::vector<std::string> args = {data_dir.string(), image_key, config.pose_key,
                                   std::to_string(budget)};
  for (const auto& pf : files) args.push_back(pf.name);
  DecoderProcess decoder(python, args);
  const json hello = decoder.next_message();
  if (hello.contains("fatal")) {
    throw Error("cannot read HoloOcean pickles: " + hello.at("fatal").get<std::string>() +
                "; install python3-numpy (scripts/install-deps.sh) or name an interpreter with "
                "numpy (--python)");
  }

  const int rows = res.sonar.range_bins, cols = res.sonar.azimuth_bins;
  std::unique_ptr<DatasetWriter> writer;
  std::string first_dtype_file;
  Trajectory navigation;
  Progress bar("import", files.size(), progress);
  std::vector<unsigned char> raw;
  for (const PickleFile& pf : files) {
    const json msg = decoder.next_message();
    const std::string where = (data_dir / pf.name).string();
    if (!msg.contains("file") || msg.at("file").get<std::string>() != pf.name) {
      throw Error(where + ": the pickle decoder answered out of order");
    }
    // Every check comes before the payload is read: on an error the decoder is stopped, so a
    // huge wrong-shaped array is never buffered.
    if (msg.contains("error")) {
      std::string why = msg.at("error").get<std::string>();
      for (char& c : why) {
        if (static_cast<unsigned char>(c) < 0x20) c = ' ';  // one line, no raw control bytes
      }
      throw Error(where + ": " + why);
    }
    const std::string dtype = msg.at("dtype").get<std::string>();
    const auto shape = msg.at("shape").get<std::vector<long>>();
    const std::string key = "'" + image_key + "'";
    if (shape.size() != 2) {
      throw Error(where + ": " + key + " has " + std::to_string(shape.size()) +
                  " dimensions; expected a 2-D image (range bins × azimuth bins)");
    }
    if (shape[0] != rows || shape[1] != cols) {
      throw Error(where + ": " + key + " is " + std::to_string(shape[0]) + "×" +
                  std::to_string(shape[1]) + " but Config.json declares RangeBins " +
                  std::to_string(rows) + " × AzimuthBins " + std::to_string(cols));
    }
    if (dtype != "uint8" && dtype != "float32") {
      throw Error(where + ": " + key + " has dtype " + dtype + "; expected uint8 or float32");
    }
    if (res.dtype.empty()) {
      res.dtype = dtype;
      first_dtype_file = pf.name;
    } else if (dtype != res.dtype) {
      throw Error(where + ": " + key + " is " + dtype + " but " + first_dtype_file + " is " +
                  res.dtype + "; a dataset keeps one pixel type");
    }
    const auto pose_shape = msg.at("pose_shape").get<std::vector<long>>();
    if (!msg.contains("pose")) {
      std::string sh;
      for (long d : pose_shape) sh += (sh.empty() ? "" : "×") + std::to_string(d);
      throw Error(where + ": '" + config.pose_key + "' is " + sh + " of " +
                  msg.at("pose_dtype").get<std::string>() + "; expected a 4×4 float matrix");
    }
    const Eigen::Isometry3d T_world_sonar =
        rigid_pose(msg.at("pose"), config.rigid_tolerance, where);

    if (!writer) {
      if (res.dtype == "uint8") {
        // Stored as 8-bit PNG; intensity = value / 255 keeps the values exactly.
        res.spec.bit_depth = 8;
        res.spec.intensity_scale = 1.0 / 255.0;
      }
      writer =
          std::make_unique<DatasetWriter>(out, res.spec,
                                          res.dtype == "uint8" ? DatasetWriter::ImageFormat::Png
                                                               : DatasetWriter::ImageFormat::Tiff);
    }
    const std::size_t nbytes = msg.value("nbytes", std::size_t{0});
    if (nbytes != static_cast<std::size_t>(rows) * cols * (dtype == "uint8" ? 1 : 4)) {
      throw Error(where + ": the pickle decoder announced " + std::to_string(nbytes) + " bytes");
    }
    raw.resize(nbytes);
    decoder.read_bytes(raw.data(), nbytes);
    SonarImage img(rows, cols);
    if (dtype == "uint8") {
      for (std::size_t k = 0; k < img.data.size(); ++k) {
        img.data[k] = static_cast<float>(raw[k] / 255.0);
      }
    } else {
      std::memcpy(img.data.data(), raw.data(), nbytes);
      for (std::size_t k = 0; k < img.data.size(); ++k) {
        if (!std::isfinite(img.data[k])) {
          throw Error(where + ": " + key + " holds a non-finite intensity at row " +
                      std::to_string(k / cols) + ", column " + std::to_string(k % cols));
        }
      }
    }
    img.timestamp = static_cast<double>(pf.number) / res.frame_rate_hz;
    writer->add_frame(img);
    navigation.push_back(img.timestamp, T_world_sonar);  // T_vehicle_sonar = identity
    bar.add();
  }
  const json done = decoder.next_message();
  if (!done.contains("done")) throw Error("the pickle decoder sent more frames than asked for");
  decoder.finish();
  bar.finish();
  writer->set_navigation(navigation);
  writer->commit();
  res.frames = files.size();
  return res;
}

}  // namespace sonar3d
