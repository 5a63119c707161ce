// sonar3d survey: import → map → recognise → world model → texture → report, resumable
// (include/sonar3d/pipeline/survey_pipeline.hpp, docs/survey.md). Every stage is the library
// call its command makes; this file only chains them, stamps them and measures them.
#include "sonar3d/pipeline/survey_pipeline.hpp"

#include <fmt/format.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/memory.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/core/point_cloud.hpp"
#include "sonar3d/core/progress.hpp"
#include "sonar3d/io/aris.hpp"
#include "sonar3d/io/dataset.hpp"
#include "sonar3d/io/holoocean.hpp"
#include "sonar3d/io/mesh_io.hpp"
#include "sonar3d/io/navigation.hpp"
#include "sonar3d/io/oculus.hpp"
#include "sonar3d/io/rosbag.hpp"
#include "sonar3d/mapping/survey.hpp"
#include "sonar3d/recog/catalogue.hpp"
#include "sonar3d/recog/model.hpp"
#include "sonar3d/recog/recognition.hpp"
#include "sonar3d/recog/recognition_3d.hpp"
#include "sonar3d/report/report.hpp"
#include "sonar3d/video/camera_dataset.hpp"
#include "sonar3d/video/texture_files.hpp"
#include "sonar3d/world/world_model.hpp"
#include "survey_options.hpp"

namespace sonar3d {

namespace fs = std::filesystem;
// Ordered: "format" stays first in summary.json, where is_sonar3d_output() looks for it.
using json = nlohmann::ordered_json;

namespace {

constexpr const char* kStages[] = {"import", "map", "recognize", "world", "texture", "report"};
constexpr int kNumStages = 6;

// ---- memory ----------------------------------------------------------------------------------

// Peak resident memory of the process, MB: VmHWM of /proc/self/status, else getrusage.
double peak_memory_mb() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;  // kB
  }
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return static_cast<double>(ru.ru_maxrss) / 1024.0;  // kB on Linux
}

// Resets VmHWM to the current resident size (Linux ≥ 4.0: "5" to clear_refs), so that each
// stage's peak is its own. False when the kernel refuses (the peak is then the process's so far).
bool reset_peak_memory() {
  std::ofstream f("/proc/self/clear_refs");
  if (!f) return false;
  f << "5";
  f.flush();
  return static_cast<bool>(f);
}

// ---- identities of inputs ---------------------------------------------------------------------

std::int64_t mtime_ns(const fs::path& p) {
  std::error_code ec;
  const auto t = fs::last_write_time(p, ec);
  if (ec) return 0;
  return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
}

// "path size mtime" for a file; for a directory its file count and a digest (FNV-1a) of every
// file's relative path, size and mtime; "missing" when absent.
std::string identity(const fs::path& p) {
  std::error_code ec;
  const std::string name = fs::absolute(p).lexically_normal().string();
  if (fs::is_regular_file(p, ec)) {
    return fmt::format("{} size {} mtime {}", name, fs::file_size(p, ec), mtime_ns(p));
  }
  if (!fs::is_directory(p, ec)) return name + " missing";
  std::vector<std::string> entries;
  for (fs::recursive_directory_iterator it(p, ec), end; !ec && it != end; it.increment(ec)) {
    if (!it->is_regular_file(ec)) continue;
    entries.push_back(fmt::format("{}\t{}\t{}", fs::relative(it->path(), p, ec).string(),
                                  it->file_size(ec), mtime_ns(it->path())));
  }
  std::sort(entries.begin(), entries.end());
  std::uint64_t h = 1469598103934665603ull;
  for (const std::string& e : entries) {
    for (unsigned char c : e) {
      h ^= c;
      h *= 1099511628211ull;
    }
    h ^= '\n';
    h *= 1099511628211ull;
  }
  return fmt::format("{} directory {} files digest {:016x}", name, entries.size(), h);
}

// ---- stage outputs: staged, then renamed into place -------------------------------------------

// Moves `staged` to `final_path`, replacing what is there: a file by one rename; a directory by
// renaming the old one aside first, then removing it.
void install(const fs::path& staged, const fs::path& final_path) {
  std::error_code ec;
  if (fs::is_directory(final_path, ec)) {
    const fs::path old = final_path.parent_path() / ("." + final_path.filename().string() + ".old");
    fs::remove_all(old);
    fs::rename(final_path, old);
    fs::rename(staged, final_path);
    fs::remove_all(old);
  } else {
    fs::rename(staged, final_path);
  }
  sync_path(final_path.parent_path());
}

void remove_output(const fs::path& p) {
  std::error_code ec;
  fs::remove_all(p, ec);
}

// ---- the input --------------------------------------------------------------------------------

std::string lower_ext(const fs::path& p) {
  std::string e = p.extension().string();
  for (char& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

bool starts_with_oculus_id(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  unsigned char b[2] = {0, 0};
  f.read(reinterpret_cast<char*>(b), 2);
  return f.gcount() == 2 && (b[0] | (b[1] << 8)) == kOculusId;
}

bool starts_with_aris_magic(const fs::path& p) {
  // ARIS files begin with the 4-byte version "DDF\x05" (and older "DDF\x03", "DDF\x04").
  std::ifstream f(p, std::ios::binary);
  char b[3] = {0, 0, 0};
  f.read(b, 3);
  return f.gcount() == 3 && b[0] == 'D' && b[1] == 'D' && b[2] == 'F';
}

bool starts_with(const fs::path& p, const std::string& magic) {
  std::ifstream f(p, std::ios::binary);
  std::string b(magic.size(), '\0');
  f.read(b.data(), static_cast<std::streamsize>(b.size()));
  return b == magic;
}

// ---- stamps -----------------------------------------------------------------------------------

json report_to_json(const SurveyStageReport& r) {
  json figures = json::object();
  for (const auto& [k, v] : r.figures) figures[k] = v;
  return json{{"name", r.name},
              {"status", r.status},
              {"note", r.note},
              {"seconds", r.seconds},
              {"peak_memory_mb", r.peak_memory_mb},
              {"figures", figures}};
}

SurveyStageReport report_from_json(const json& j) {
  SurveyStageReport r;
  r.name = j.value("name", "");
  r.status = j.value("status", "");
  r.note = j.value("note", "");
  r.seconds = j.value("seconds", 0.0);
  r.peak_memory_mb = j.value("peak_memory_mb", 0.0);
  if (j.contains("figures") && j["figures"].is_object()) {
    for (const auto& [k, v] : j["figures"].items()) {
      if (v.is_number()) r.figures.emplace_back(k, v.get<double>());
    }
  }
  return r;
}

class Survey {
 public:
  explicit Survey(const SurveyOptions& o) : o_(o), out_(o.output) {}

  SurveyResult run();

 private:
  // What a stage is made from: its inputs' identities and its settings.
  std::string stamp_key(const std::string& stage, const std::vector<fs::path>& inputs,
                        const std::string& extra = "") const {
    std::string k = "stage: " + stage + "\ninputs:\n";
    for (const fs::path& p : inputs) k += "  - " + identity(p) + "\n";
    if (!extra.empty()) k += extra + "\n";
    k += "settings:\n" + survey_detail::stage_settings(o_.config, stage, kind_);
    return k;
  }
  fs::path stamp_path(const std::string& stage) const {
    return out_ / "stamps" / (stage + ".json");
  }
  std::optional<SurveyStageReport> matching_stamp(const std::string& stage,
                                                  const std::string& key) const {
    std::error_code ec;
    const fs::path p = stamp_path(stage);
    if (!fs::is_regular_file(p, ec)) return std::nullopt;
    try {
      const json j = json::parse(read_text_file(p.string()));
      if (j.value("key", "") != key) return std::nullopt;
      return report_from_json(j.at("report"));
    } catch (const std::exception&) {
      return std::nullopt;  // unreadable: run the stage again
    }
  }
  void write_stamp(const std::string& stage, const std::string& key,
                   const SurveyStageReport& r) const {
    fs::create_directories(out_ / "stamps");
    json j{{"format", "sonar3d-survey-stamp"}, {"key", key}, {"report", report_to_json(r)}};
    write_text_file(stamp_path(stage).string(), j.dump(2) + "\n");
  }
  void drop_stamp(const std::string& stage) const {
    std::error_code ec;
    fs::remove(stamp_path(stage), ec);
  }
  // A fresh staging directory inside OUT for a stage's outputs.
  fs::path staging(const std::string& stage) const {
    const fs::path s = out_ / (".staging-" + stage);
    fs::remove_all(s);
    fs::create_directories(s);
    return s;
  }

  void write_summary(const std::string& failed_stage = "", const std::string& error = "");
  void warn(const std::string& w) const {
    if (o_.on_warning) o_.on_warning(w);
  }

  // Runs `stage` unless its stamp matches (and nothing before it ran); `body` fills the report.
  template <class Body>
  void stage(int k, const std::string& name, const std::vector<fs::path>& inputs, Body&& body,
             const std::string& extra = "");
  void skip(int k, const std::string& name, const std::string& note,
            const std::vector<fs::path>& outputs);

  // The stages' work.
  void do_import(SurveyStageReport& r);
  void do_map(SurveyStageReport& r);
  void do_recognize(SurveyStageReport& r);
  void do_world(SurveyStageReport& r);
  void do_texture(SurveyStageReport& r);
  void do_report(SurveyStageReport& r);

  const SurveyOptions& o_;
  fs::path out_;
  std::string kind_;
  fs::path dataset_;
  bool upstream_ran_ = false;
  bool peak_reset_ok_ = true;
  std::vector<SurveyStageReport> reports_;
  double seconds_ = 0;
};

template <class Body>
void Survey::stage(int k, const std::string& name, const std::vector<fs::path>& inputs, Body&& body,
                   const std::string& extra) {
  if (o_.on_stage) o_.on_stage(k, kNumStages, name, "start");
  // For a caller's progress callback (the Python bindings): the stage, then its own bars.
  Progress marker(fmt::format("survey {}/{} {}", k, kNumStages, name), 1, false);
  const std::string key = stamp_key(name, inputs, extra);
  if (!upstream_ran_) {
    if (auto done = matching_stamp(name, key)) {
      done->status = "unchanged";
      reports_.push_back(*done);
      marker.finish();
      if (o_.on_stage) o_.on_stage(k, kNumStages, name, "unchanged");
      return;
    }
  }
  // This stage runs: it and every later one lose their stamps first, so that an interruption
  // from here on re-runs them.
  bool later = false;
  for (const char* s : kStages) {
    if (s == name) later = true;
    if (later) drop_stamp(s);
  }
  upstream_ran_ = true;
  SurveyStageReport r;
  r.name = name;
  r.status = "ran";
  peak_reset_ok_ = reset_peak_memory() && peak_reset_ok_;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    body(r);
  } catch (const Interrupted&) {
    throw;
  } catch (const std::exception& e) {
    std::error_code ec;
    fs::remove_all(out_ / (".staging-" + name), ec);
    r.status = "failed";
    r.note = e.what();
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    reports_.push_back(r);
    write_summary(name, e.what());
    throw Error("survey: stage " + name + " failed: " + e.what());
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.peak_memory_mb = peak_memory_mb();
  std::error_code ec;
  fs::remove_all(out_ / (".staging-" + name), ec);
  // The stamp names the inputs as they are now, after the stage (its own outputs are not inputs).
  write_stamp(name, stamp_key(name, inputs, extra), r);
  reports_.push_back(r);
  write_summary();
  marker.finish();
  if (o_.on_stage) o_.on_stage(k, kNumStages, name, "ran");
}

void Survey::skip(int k, const std::string& name, const std::string& note,
                  const std::vector<fs::path>& outputs) {
  if (o_.on_stage) o_.on_stage(k, kNumStages, name, "start");
  // Outputs of an earlier run in which the stage applied are stale now: removed.
  for (const fs::path& p : outputs) remove_output(p);
  drop_stamp(name);
  SurveyStageReport r;
  r.name = name;
  r.status = "skipped";
  r.note = note;
  reports_.push_back(r);
  write_summary();
  if (o_.on_stage) o_.on_stage(k, kNumStages, name, "skipped");
}

void Survey::write_summary(const std::string& failed_stage, const std::string& error) {
  json stages = json::array();
  for (const SurveyStageReport& r : reports_) stages.push_back(report_to_json(r));
  auto abs = [](const fs::path& p) {
    return p.empty() ? std::string() : fs::absolute(p).lexically_normal().string();
  };
  double peak = 0;  // over the stages that ran in this process
  for (const SurveyStageReport& r : reports_) {
    if (r.status == "ran") peak = std::max(peak, r.peak_memory_mb);
  }
  json j{{"format", "sonar3d-survey"},
         {"version", 1},
         {"input", abs(o_.input)},
         {"input_kind", kind_},
         {"dataset", abs(dataset_)},
         {"catalogue", abs(o_.catalogue)},
         {"config_file", abs(o_.config_file)},
         {"stages", stages},
         {"seconds", seconds_},
         {"peak_memory_mb", peak},
         {"peak_memory_per_stage", peak_reset_ok_}};
  if (!failed_stage.empty()) {
    j["failed_stage"] = failed_stage;
    j["error"] = error;
  }
  write_text_file((out_ / "summary.json").string(), j.dump(2) + "\n");
}

// ---- import ------------------------------------------------------------------------------------

// The files an import reads besides the input: its navigation file, its sensor description.
std::vector<fs::path> import_files(const SurveyImportOptions& c, const std::string& kind) {
  std::vector<fs::path> files;
  const std::string& f = kind == "aris"     ? c.aris.navigation
                         : kind == "oculus" ? c.oculus.navigation
                         : kind == "rosbag" ? c.rosbag.sonar_description
                                            : std::string();
  if (!f.empty()) files.emplace_back(f);
  return files;
}

void Survey::do_import(SurveyStageReport& r) {
  // The importer's own configuration, as `sonar3d import <kind>` runs it (each validates it).
  const SurveyImportOptions& c = o_.config.import;
  OutputPolicy policy;
  policy.overwrite = true;  // the survey's own dataset/ (a sonar3d dataset) is replaced
  policy.sources = {o_.input};
  for (const fs::path& f : import_files(c, kind_)) policy.sources.push_back(f);
  policy.on_note = [this](const std::string& n) { warn(n); };
  OutputDirectory dest(dataset_, OutputKind::Dataset, policy);
  std::size_t frames = 0;
  std::vector<std::string> warnings;
  if (kind_ == "aris") {
    const ArisImportResult res = import_aris(o_.input, dest.staging(), c.aris, o_.progress);
    frames = res.frames;
    warnings = res.warnings;
    r.figures.emplace_back("dropped", static_cast<double>(res.dropped));
  } else if (kind_ == "rosbag") {
    RosbagImportConfig b = c.rosbag;
    // Topics not named in the configuration are found by message type when unambiguous.
    for (const std::string& line : choose_rosbag_topics(o_.input, b)) r.note += line + "; ";
    const RosbagImportResult res = import_rosbag(o_.input, dest.staging(), b, o_.progress);
    frames = res.frames;
    warnings = res.warnings;
    r.figures.emplace_back("dropped", static_cast<double>(res.dropped));
    r.figures.emplace_back("navigation_samples", static_cast<double>(res.navigation_samples));
  } else if (kind_ == "oculus") {
    const OculusImportResult res = import_oculus(o_.input, dest.staging(), c.oculus, o_.progress);
    frames = res.frames;
    warnings = res.warnings;
    r.figures.emplace_back("pings", static_cast<double>(res.pings));
    r.figures.emplace_back("dropped", static_cast<double>(res.dropped));
  } else if (kind_ == "holoocean") {
    const HoloOceanImportResult res =
        import_holoocean(o_.input, dest.staging(), c.holoocean, o_.progress);
    frames = res.frames;
    warnings = res.warnings;
  } else {
    throw Error("no importer for input kind '" + kind_ + "'");
  }
  dest.commit();
  for (const std::string& w : warnings) warn(o_.input.string() + ": " + w);
  r.note += kind_ + " imported into " + dataset_.string();
  r.figures.emplace_back("frames", static_cast<double>(frames));
}

// ---- map ---------------------------------------------------------------------------------------

void Survey::do_map(SurveyStageReport& r) {
  const SurveyMapOptions& c = o_.config.map;
  MapSurveyConfig cfg = c.map;
  cfg.registration.num_threads = cfg.carve.num_threads;
  cfg.validate();
  const Dataset ds = read_dataset(dataset_);
  const double limit = c.max_memory_gb > 0 ? c.max_memory_gb * 1e9 : default_memory_limit_bytes();
  check_memory(estimate_map_survey_memory(ds, cfg, limit), limit, "survey (map)");
  const fs::path s = staging("map");
  const MapSurveyResult m = map_survey(ds, cfg, s / "map", o_.progress);
  install(s / "map", out_ / "map");
  std::size_t used = 0;
  for (bool u : m.adjustment.tie_used) used += u;
  r.figures = {{"frames", static_cast<double>(ds.size())},
               {"swaths", static_cast<double>(m.swaths.size())},
               {"points", static_cast<double>(m.merged_points)},
               {"ties", static_cast<double>(m.ties.size())},
               {"ties_used", static_cast<double>(used)},
               {"seconds_carving", m.seconds_carving},
               {"seconds_registration", m.seconds_registration}};
  if (m.has_alignment) {
    r.figures.emplace_back("navigation_error_before_m", m.navigation_before.rigid_m);
    r.figures.emplace_back("navigation_error_after_m", m.navigation_after.rigid_m);
  }
  r.note = fmt::format("{} method", to_string(cfg.method));
}

// ---- recognise ---------------------------------------------------------------------------------

void Survey::do_recognize(SurveyStageReport& r) {
  const RecognizeConfig& c = o_.config.recognize;  // as sonar3d recognize runs it
  c.validate();
  const Catalogue cat = read_catalogue(o_.catalogue.string());
  std::vector<ModelTemplate> models;
  const ModelSamplingConfig& sampling = c.method == "3d" ? c.three_d.sampling : c.two_d.sampling;
  for (const auto& m : cat.models) models.push_back(make_catalogue_template(cat, m, sampling));
  const fs::path map_dir = out_ / "map";
  const PointCloud scene = read_ply((map_dir / "merged.ply").string());
  std::vector<Search3dRecord> searches3;
  const RecognitionResult res = recognize(scene, models, c, &searches3, o_.progress);
  const fs::path s = staging("recognize");
  save_mesh((s / "placements.ply").string(), placed_models_mesh(models, res.placements));
  write_text_file((s / "placements.json").string(),
                  recognize_json(res, searches3, map_dir.string(), o_.catalogue.string(), c));
  // The mesh first: placements.json names a complete set.
  install(s / "placements.ply", out_ / "placements.ply");
  install(s / "placements.json", out_ / "placements.json");
  std::size_t rejected = 0;
  for (const auto& sr : res.searches) rejected += !sr.accepted && sr.scan.found;
  r.figures = {{"models", static_cast<double>(models.size())},
               {"scene_points", static_cast<double>(scene.size())},
               {"placements", static_cast<double>(res.placements.size())},
               {"candidates_rejected", static_cast<double>(rejected)}};
  std::string placed;
  for (const Placement& p : res.placements) placed += (placed.empty() ? "" : ", ") + p.model;
  r.note = fmt::format("{} method; placed: {}", c.method, placed.empty() ? "none" : placed);
}

// ---- world model -------------------------------------------------------------------------------

void Survey::do_world(SurveyStageReport& r) {
  const SurveyWorldOptions& c = o_.config.world;
  WorldModelConfig cfg = c.model;
  cfg.validate();
  const fs::path map_dir = out_ / "map";
  const fs::path cloud_path = map_dir / "merged.ply";
  std::vector<GivenConnection> given;
  if (!c.connections.empty()) given = read_given_connections(c.connections);
  std::vector<WorldObject> objects;
  WorldWriteInfo info;
  info.map = map_dir.string();
  if (!o_.catalogue.empty()) {
    const fs::path placements_path = out_ / "placements.json";
    const PlacementsFile placements = read_placements(placements_path.string());
    cfg.min_confidence =
        world_confidence_threshold(placements, cfg.min_confidence, "world.min_confidence");
    objects = world_objects(placements, read_catalogue(o_.catalogue.string()));
    info.placements = placements_path.string();
    info.catalogue = o_.catalogue.string();
  }
  const PointCloud cloud = read_ply(cloud_path.string());
  require(!cloud.empty(), "map '" + cloud_path.string() + "' holds no points");
  WorldModel w = build_world_model(cloud, std::move(objects), cfg);
  add_given_connections(w, given, c.connections, cfg.seabed.margin_m);
  info.cloud_bytes = fs::file_size(cloud_path);
  info.glb_all_lods = c.glb_all_lods;
  std::optional<SeabedTruth> truth;
  try {
    truth = find_seabed_truth(map_dir, "");
  } catch (const Error& e) {
    warn(std::string("world: the seabed's error is not measured: ") + e.what());
  }
  double lod0_error = std::nan("");
  if (truth) {
    for (const SeabedLod& lod : w.seabed) {
      info.seabed_error_m.push_back(seabed_error(lod.mesh, *truth).median_m);
    }
    if (!info.seabed_error_m.empty()) lod0_error = info.seabed_error_m.front();
  }
  const fs::path s = staging("world");
  const WorldWriteResult res = write_world_model(s / "world", w, info);
  install(s / "world", out_ / "world");
  std::size_t confirmed = 0, found = 0;
  for (const WorldObject& ob : w.objects) confirmed += ob.confirmed;
  for (const Connection& cn : w.connections) found += cn.found;
  r.figures = {{"cloud_points", static_cast<double>(w.cloud_points)},
               {"seabed_points", static_cast<double>(w.seabed_points)},
               {"objects", static_cast<double>(confirmed)},
               {"unconfirmed_objects", static_cast<double>(w.objects.size() - confirmed)},
               {"connections", static_cast<double>(found)},
               {"seabed_lods", static_cast<double>(w.seabed.size())},
               {"glb_bytes", static_cast<double>(res.glb_bytes)},
               {"bytes_total", static_cast<double>(res.bytes_total)}};
  if (std::isfinite(lod0_error)) r.figures.emplace_back("seabed_error_lod0_m", lod0_error);
  if (o_.catalogue.empty()) r.note = "no catalogue: the seabed only";
}

// ---- texture -----------------------------------------------------------------------------------

void Survey::do_texture(SurveyStageReport& r) {
  const SurveyTextureOptions& c = o_.config.texture;
  TextureFilesJob job;
  job.cloud = out_ / "map" / "merged.ply";
  job.dataset_dir = dataset_;
  // The corrected navigation places the video where the corrected map is.
  job.navigation_file = out_ / "map" / "navigation_corrected.tum";
  job.config = c.texture.texture;
  job.poses = c.texture.poses;
  job.drop_uncoloured = c.drop_uncoloured;
  job.progress = o_.progress;
  const fs::path s = staging("texture");
  job.output = s / "textured.ply";
  const TextureFilesResult res = texture_cloud_files(job);
  install(s / "textured.ply", out_ / "textured.ply");
  r.figures = {{"points", static_cast<double>(res.points)},
               {"coloured", static_cast<double>(res.coloured)},
               {"frames", static_cast<double>(res.frames)}};
}

// ---- report ------------------------------------------------------------------------------------

void Survey::do_report(SurveyStageReport& r) {
  const SurveyReportOptions& c = o_.config.report;
  ReportConfig cfg = c.report;
  if (cfg.title.empty()) cfg.title = "sonar3d survey: " + fs::absolute(out_).filename().string();
  cfg.web_dir = c.web_dir;
  cfg.progress = o_.progress;
  std::error_code ec;
  if (fs::is_regular_file(out_ / "textured.ply", ec)) cfg.overlays.push_back(out_ / "textured.ply");
  const fs::path s = staging("report");
  cfg.output = s / "report.html";
  const ReportSummary res = write_report(out_ / "world", cfg);
  for (const std::string& w : res.warnings) warn("report: " + w);
  install(s / "report.html", out_ / "report.html");
  r.figures = {{"bytes", static_cast<double>(res.bytes)},
               {"layers", static_cast<double>(res.num_layers)},
               {"points_shown", static_cast<double>(res.num_cloud_points)},
               {"mesh_triangles_shown", static_cast<double>(res.num_mesh_triangles)}};
}

// ---- the run -----------------------------------------------------------------------------------

SurveyResult Survey::run() {
  const auto t0 = std::chrono::steady_clock::now();
  require(!o_.input.empty(), "survey: no input given");
  std::error_code ec;
  require(fs::exists(o_.input, ec), "survey: input '" + o_.input.string() + "' does not exist");
  if (!o_.catalogue.empty()) {
    require(fs::is_regular_file(o_.catalogue, ec),
            "survey: catalogue '" + o_.catalogue.string() + "' is not a file");
  }
  // The output rule: OUT is new, empty, or a survey directory (resumed); never an input, inside
  // one, or holding one.
  OutputPolicy policy;
  policy.sources = {o_.input};
  if (!o_.catalogue.empty()) policy.sources.push_back(o_.catalogue);
  if (!o_.config_file.empty()) policy.sources.push_back(o_.config_file);
  policy.on_note = [this](const std::string& n) { warn(n); };
  if (fs::exists(out_, ec) && is_sonar3d_output(out_, OutputKind::Survey)) {
    check_output_location(out_, policy, "-o", "survey directory");
  } else {
    check_output(out_, OutputKind::Survey, policy, "-o");
  }
  kind_ = o_.config.import.kind == "auto" ? survey_input_kind(o_.input) : o_.config.import.kind;
  require(
      kind_ != "auto" && std::find(std::begin(kSurveyInputKinds), std::end(kSurveyInputKinds),
                                   kind_) != std::end(kSurveyInputKinds),
      "import.kind must be auto, dataset, aris, rosbag, holoocean or oculus, not '" + kind_ + "'");
  fs::create_directories(out_);
  dataset_ = kind_ == "dataset" ? o_.input : out_ / "dataset";
  write_summary();  // marks OUT as a survey directory from the start

  // 1. import
  if (kind_ == "dataset") {
    skip(1, "import", "the input is a dataset: used in place (read-only)", {out_ / "dataset"});
  } else {
    std::vector<fs::path> in = {o_.input};
    for (const fs::path& f : import_files(o_.config.import, kind_)) in.push_back(f);
    // The dataset itself too: one removed or changed by hand is imported again.
    in.push_back(dataset_);
    stage(
        1, "import", in, [&](SurveyStageReport& r) { do_import(r); }, "kind: " + kind_);
  }
  // 2. map
  stage(2, "map", {dataset_}, [&](SurveyStageReport& r) { do_map(r); });
  // 3. recognise
  const fs::path merged = out_ / "map" / "merged.ply";
  if (o_.catalogue.empty()) {
    skip(3, "recognize", "no catalogue (--catalogue)",
         {out_ / "placements.json", out_ / "placements.ply"});
  } else {
    std::vector<fs::path> in = {merged, o_.catalogue};
    try {  // the catalogue's mesh files are inputs too
      for (const CatalogueModel& m : read_catalogue(o_.catalogue.string()).models) {
        if (!m.mesh_path.empty()) in.push_back(m.mesh_path);
      }
    } catch (const Error&) {
      // an unreadable catalogue fails inside the stage, naming it
    }
    stage(3, "recognize", in, [&](SurveyStageReport& r) { do_recognize(r); });
  }
  // 4. world model
  {
    std::vector<fs::path> in = {merged};
    if (!o_.catalogue.empty()) {
      in.push_back(out_ / "placements.json");
      in.push_back(o_.catalogue);
    }
    if (!o_.config.world.connections.empty()) in.push_back(o_.config.world.connections);
    stage(4, "world", in, [&](SurveyStageReport& r) { do_world(r); });
  }
  // 5. texture
  if (!has_camera_frames(dataset_)) {
    skip(5, "texture", "the log has no camera images (dataset camera/)", {out_ / "textured.ply"});
  } else {
    stage(5, "texture", {merged, out_ / "map" / "navigation_corrected.tum", dataset_ / "camera"},
          [&](SurveyStageReport& r) { do_texture(r); });
  }
  // 6. report
  {
    std::vector<fs::path> in = {out_ / "world"};
    if (fs::is_regular_file(out_ / "textured.ply", ec)) in.push_back(out_ / "textured.ply");
    if (!o_.config.report.web_dir.empty()) in.push_back(o_.config.report.web_dir);
    stage(6, "report", in, [&](SurveyStageReport& r) { do_report(r); });
  }
  seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  write_summary();
  SurveyResult result;
  result.stages = reports_;
  result.dataset = dataset_;
  result.seconds = seconds_;
  result.summary_json = read_text_file((out_ / "summary.json").string());
  return result;
}

}  // namespace

std::string survey_input_kind(const fs::path& input) {
  std::error_code ec;
  if (fs::is_directory(input, ec)) {
    if (fs::is_regular_file(input / "sonar.yaml", ec)) return "dataset";
    if (fs::is_regular_file(input / "Config.json", ec) && fs::is_directory(input / "Data", ec)) {
      return "holoocean";
    }
    if (fs::is_regular_file(input / "metadata.yaml", ec)) return "rosbag";
    for (fs::directory_iterator it(input, ec), end; !ec && it != end; it.increment(ec)) {
      if (lower_ext(it->path()) == ".db3") return "rosbag";
    }
  } else if (fs::is_regular_file(input, ec)) {
    const std::string e = lower_ext(input);
    if (e == ".aris" || starts_with_aris_magic(input)) return "aris";
    if (e == ".bag" || e == ".db3" || starts_with(input, "#ROSBAG V2.0")) return "rosbag";
    if (starts_with(input, "SQLite format 3")) return "rosbag";
    if (starts_with_oculus_id(input)) return "oculus";
  }
  throw Error("survey: '" + input.string() +
              "' is not an input sonar3d can survey: give a dataset directory (sonar.yaml), an "
              "ARIS file (.aris), a ROS 1 bag (.bag) or ROS 2 bag (directory with metadata.yaml, "
              "or .db3), a HoloOcean recording (directory with Config.json and Data/) or an "
              "Oculus ping stream (messages starting 0x4f53), or set import.kind");
}

SurveyResult run_survey(const SurveyOptions& options) {
  Survey s(options);
  return s.run();
}

}  // namespace sonar3d
