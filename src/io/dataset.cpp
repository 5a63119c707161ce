#include "sonar3d/io/dataset.hpp"

#include <cmath>
#include <fstream>
#include <iomanip>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "image_header.hpp"
#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/output_dir.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/core/limits.hpp"
#include "sonar3d/io/yaml_config.hpp"

namespace fs = std::filesystem;

namespace sonar3d {
namespace {

SonarImage from_mat(const cv::Mat& m, double scale) {
  SonarImage img(m.rows, m.cols);
  cv::Mat f(m.rows, m.cols, CV_32F, img.data.data());
  m.convertTo(f, CV_32F, scale);
  return img;
}

cv::Mat to_mat(const SonarImage& img) {
  return cv::Mat(img.rows, img.cols, CV_32F, const_cast<float*>(img.data.data()));
}

// The header of a PNG or TIFF image, checked before OpenCV allocates its pixels.
detail::ImageHeader checked_header(const std::string& path, const char* what) {
  const detail::ImageHeader h = detail::read_image_header(path);
  if (!h.known) {
    throw Error(std::string(what) + " '" + path + "' is neither a PNG nor a TIFF image");
  }
  if (static_cast<double>(h.width) * h.height > limits::kMaxPixels) {
    throw Error(std::string(what) + " '" + path + "' declares " + std::to_string(h.width) + "×" +
                std::to_string(h.height) + " pixels, more than the limit of " +
                std::to_string(static_cast<long long>(limits::kMaxPixels)));
  }
  return h;
}

std::string frame_name(int index, const char* ext) {
  std::ostringstream os;
  os << "frames/" << std::setw(6) << std::setfill('0') << index << ext;
  return os.str();
}

}  // namespace

SonarImage read_float_image(const std::string& path) {
  if (!fs::exists(path)) throw Error("image '" + path + "' does not exist");
  checked_header(path, "image");
  const cv::Mat m = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (m.empty()) throw Error("cannot decode image '" + path + "' (corrupt or unsupported)");
  if (m.channels() != 1) {
    throw Error("image '" + path + "' has " + std::to_string(m.channels()) +
                " channels; expected one");
  }
  SonarImage img = from_mat(m, 1.0);
  for (float v : img.data) {
    if (!std::isfinite(v)) throw Error("image '" + path + "' holds a non-finite value");
  }
  return img;
}

void write_float_image(const std::string& path, const SonarImage& image) {
  AtomicPath out(path);
  const std::string tmp = out.temp().string() + fs::path(path).extension().string();
  if (!cv::imwrite(tmp, to_mat(image))) throw Error("cannot write image '" + path + "'");
  const std::string ext = fs::path(path).extension().string();
  if (ext == ".tif" || ext == ".tiff") mark_tiff_as_sonar3d(tmp);  // replaceable by sonar3d only
  fs::rename(tmp, out.temp());
  out.commit();
}

SonarImage read_sonar_image(const std::string& path, const SonarSpec& spec) {
  if (!fs::exists(path)) throw Error("frame '" + path + "' does not exist");
  const detail::ImageHeader h = checked_header(path, "frame");
  if (h.width != spec.beams() || h.height != spec.range_bins) {
    throw Error("frame '" + path + "' is " + std::to_string(h.height) + "×" +
                std::to_string(h.width) + " (rows×cols) but sonar.yaml declares " +
                std::to_string(spec.range_bins) + " range bins × " + std::to_string(spec.beams()) +
                " beams");
  }
  const cv::Mat m = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (m.empty()) throw Error("cannot decode frame '" + path + "' (corrupt or unsupported image)");
  if (m.channels() != 1) {
    throw Error("frame '" + path + "' has " + std::to_string(m.channels()) +
                " channels; sonar frames are single-channel");
  }
  if (m.rows != spec.range_bins || m.cols != spec.beams()) {
    throw Error("frame '" + path + "' is " + std::to_string(m.rows) + "×" + std::to_string(m.cols) +
                " (rows×cols) but sonar.yaml declares " + std::to_string(spec.range_bins) +
                " range bins × " + std::to_string(spec.beams()) + " beams");
  }
  const int depth = m.depth();
  double scale = 1.0;
  if (depth == CV_8U || depth == CV_16U) {
    // An 8-bit frame in a 16-bit dataset would read 256× too dark (and the reverse too bright).
    const int bits = depth == CV_8U ? 8 : 16;
    if (bits != spec.bit_depth) {
      throw Error("frame '" + path + "' is a " + std::to_string(bits) +
                  "-bit image but sonar.yaml declares intensity.bit_depth " +
                  std::to_string(spec.bit_depth) + "; re-export the frame at " +
                  std::to_string(spec.bit_depth) + " bits");
    }
    scale = spec.intensity_scale;
  } else if (depth != CV_32F) {
    throw Error("frame '" + path + "': pixel type must be 8/16-bit unsigned or float32");
  }
  SonarImage img = from_mat(m, scale);
  if (depth == CV_32F) {
    for (float v : img.data) {
      if (!std::isfinite(v)) throw Error("frame '" + path + "' holds a non-finite intensity");
    }
  }
  return img;
}

void write_sonar_image(const std::string& path, const SonarImage& image, const SonarSpec& spec) {
  const std::string ext = fs::path(path).extension().string();
  if (ext == ".tiff" || ext == ".tif") {
    if (!cv::imwrite(path, to_mat(image))) throw Error("cannot write frame '" + path + "'");
    return;
  }
  // Quantise: stored = round(I / scale), clamped to the bit depth (the sensor saturates).
  const int type = spec.bit_depth == 8 ? CV_8U : CV_16U;
  cv::Mat q;
  to_mat(image).convertTo(q, type, 1.0 / spec.intensity_scale);  // saturate_cast rounds, clamps
  if (!cv::imwrite(path, q)) throw Error("cannot write frame '" + path + "'");
}

// ---------------------------------------------------------------- reading

SonarImage Dataset::load_frame(std::size_t i) const {
  if (i >= frames.size()) {
    throw Error("frame " + std::to_string(i) + " does not exist (dataset has " +
                std::to_string(frames.size()) + " frames)");
  }
  SonarImage img = read_sonar_image((root / frames[i].file).string(), spec);
  img.timestamp = frames[i].timestamp;
  return img;
}

Eigen::Isometry3d Dataset::T_world_sonar(std::size_t i) const {
  if (i >= frames.size()) throw Error("frame " + std::to_string(i) + " does not exist");
  try {
    return navigation.interpolate(frames[i].timestamp) * spec.T_vehicle_sonar;
  } catch (const Error& e) {
    throw Error((root / "frames.csv").string() + ": frame " + std::to_string(frames[i].index) +
                " has no pose: " + e.what());
  }
}

bool Dataset::has_truth() const { return fs::exists(truth_dir() / "scene.yaml"); }

std::vector<FrameRecord> read_frames_csv(const fs::path& path) {
  // index,timestamp,file
  const std::string csv = path.string();
  std::ifstream f(path);
  if (!f) throw Error("cannot read '" + csv + "'");
  std::vector<FrameRecord> frames;
  std::string line;
  int lineno = 0;
  bool header = true;
  std::map<int, int> index_line;  // frame index -> line of frames.csv
  while (std::getline(f, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    if (header) {
      header = false;
      if (line != "index,timestamp,file") {
        throw Error(csv + ":" + std::to_string(lineno) +
                    ": expected the header 'index,timestamp,file'");
      }
      continue;
    }
    std::istringstream is(line);
    std::string a, b, c;
    if (!std::getline(is, a, ',') || !std::getline(is, b, ',') || !std::getline(is, c)) {
      throw Error(csv + ":" + std::to_string(lineno) + ": expected 'index,timestamp,file'");
    }
    FrameRecord r;
    try {
      std::size_t pa = 0, pb = 0;
      r.index = std::stoi(a, &pa);
      r.timestamp = std::stod(b, &pb);
      if (pa != a.size() || pb != b.size()) throw std::invalid_argument("trailing");
    } catch (const std::exception&) {
      throw Error(csv + ":" + std::to_string(lineno) + ": index or timestamp is not a number");
    }
    if (!std::isfinite(r.timestamp)) {
      throw Error(csv + ":" + std::to_string(lineno) + ": timestamp is not finite");
    }
    if (!frames.empty() && r.timestamp < frames.back().timestamp) {
      throw Error(csv + ":" + std::to_string(lineno) + ": timestamps go backwards");
    }
    if (c.empty() || fs::path(c).is_absolute() || c.find("..") != std::string::npos) {
      throw Error(csv + ":" + std::to_string(lineno) +
                  ": file must be a relative path inside the dataset");
    }
    r.file = c;
    if (const auto [it, fresh] = index_line.emplace(r.index, lineno); !fresh) {
      throw Error(csv + ":" + std::to_string(lineno) + ": frame index " + std::to_string(r.index) +
                  " repeats line " + std::to_string(it->second) +
                  "; every frame needs its own index");
    }
    frames.push_back(r);
  }
  return frames;
}

std::string frames_csv_text(const std::vector<FrameRecord>& frames) {
  std::ostringstream csv;
  csv << "index,timestamp,file\n" << std::setprecision(17);
  for (const auto& r : frames) csv << r.index << ',' << r.timestamp << ',' << r.file << '\n';
  return csv.str();
}

Dataset read_dataset(const fs::path& dir) {
  if (!fs::is_directory(dir)) throw Error("dataset '" + dir.string() + "' is not a directory");
  Dataset ds;
  ds.root = dir;
  const std::string yaml_path = (dir / "sonar.yaml").string();
  if (!fs::exists(yaml_path)) {
    throw Error("'" + dir.string() + "' is not a sonar3d dataset: sonar.yaml is missing");
  }
  YAML::Node root = yaml::load_file(yaml_path);
  if (!root.IsMap()) throw Error(yaml_path + ": expected a mapping at the top level");
  const int version = yaml::get_int(root, "version", -1, yaml_path);
  if (version != kDatasetVersion) {
    throw Error(yaml::where(yaml_path, root, "version") + ": unsupported dataset version " +
                std::to_string(version) + " (this build reads version " +
                std::to_string(kDatasetVersion) + ")");
  }
  yaml::check_keys(root, {"format", "version", "sensor", "noise"}, yaml_path);
  if (!root["sensor"]) throw Error(yaml_path + ": required key 'sensor' is missing");
  ds.spec = yaml::parse_sonar_spec(root["sensor"], yaml_path, "sensor");

  const fs::path csv = dir / "frames.csv";
  if (!fs::exists(csv)) throw Error("dataset '" + dir.string() + "': frames.csv is missing");
  ds.frames = read_frames_csv(csv);

  const std::string nav = (dir / "navigation.tum").string();
  if (!fs::exists(nav)) throw Error("dataset '" + dir.string() + "': navigation.tum is missing");
  ds.navigation = read_tum(nav);
  ds.navigation.validate(nav);

  if (const YAML::Node noise = root["noise"]) {
    yaml::check_keys(noise, {"mean", "std"}, yaml_path, "noise");
    NoiseImages n;
    n.mean =
        read_float_image((dir / yaml::get_string(noise, "mean", "", yaml_path, "noise")).string());
    n.std =
        read_float_image((dir / yaml::get_string(noise, "std", "", yaml_path, "noise")).string());
    for (const SonarImage* im : {&n.mean, &n.std}) {
      if (im->rows != ds.spec.range_bins || im->cols != ds.spec.beams()) {
        throw Error(yaml_path + ": noise images must be " + std::to_string(ds.spec.range_bins) +
                    "×" + std::to_string(ds.spec.beams()) + " (range bins × beams)");
      }
    }
    ds.noise = std::move(n);
  }
  return ds;
}

// ---------------------------------------------------------------- writing

struct DatasetWriter::Impl {
  AtomicPath out;
  SonarSpec spec;
  ImageFormat format;
  std::vector<FrameRecord> frames;
  Trajectory navigation;
  std::optional<NoiseImages> noise;
  Impl(const fs::path& dir, const SonarSpec& s, ImageFormat f) : out(dir), spec(s), format(f) {}
};

DatasetWriter::DatasetWriter(const fs::path& dir, const SonarSpec& spec, ImageFormat format)
    : impl_(std::make_unique<Impl>(dir, spec, format)) {
  spec.validate();
  fs::create_directories(impl_->out.temp() / "frames");
}

DatasetWriter::~DatasetWriter() = default;

int DatasetWriter::add_frame(const SonarImage& image) {
  const SonarSpec& s = impl_->spec;
  if (image.rows != s.range_bins || image.cols != s.beams()) {
    throw Error("frame " + std::to_string(impl_->frames.size()) + " is " +
                std::to_string(image.rows) + "×" + std::to_string(image.cols) + "; the sonar has " +
                std::to_string(s.range_bins) + " range bins × " + std::to_string(s.beams()) +
                " beams");
  }
  FrameRecord r;
  r.index = static_cast<int>(impl_->frames.size());
  r.timestamp = image.timestamp;
  if (!impl_->frames.empty() && r.timestamp < impl_->frames.back().timestamp) {
    throw Error("frame " + std::to_string(r.index) + ": timestamps go backwards");
  }
  r.file = frame_name(r.index, impl_->format == ImageFormat::Png ? ".png" : ".tiff");
  write_sonar_image((impl_->out.temp() / r.file).string(), image, s);
  impl_->frames.push_back(r);
  return r.index;
}

void DatasetWriter::set_navigation(const Trajectory& T_world_vehicle) {
  T_world_vehicle.validate("navigation");
  impl_->navigation = T_world_vehicle;
}

void DatasetWriter::set_noise(const NoiseImages& noise) { impl_->noise = noise; }

fs::path DatasetWriter::truth_dir() { return part_dir("truth"); }

fs::path DatasetWriter::part_dir(const std::string& name) {
  const fs::path p = impl_->out.temp() / name;
  fs::create_directories(p);
  return p;
}

std::string sonar_spec_to_yaml(const SonarSpec& spec) {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::BeginMap;
  yaml::emit_sonar_spec(out, spec);
  out << YAML::EndMap;
  return out.c_str();
}

void DatasetWriter::commit() {
  const fs::path tmp = impl_->out.temp();
  if (impl_->navigation.empty()) throw Error("dataset has no navigation");
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << "sonar3d-dataset";
  out << YAML::Key << "version" << YAML::Value << kDatasetVersion;
  out << YAML::Key << "sensor" << YAML::Value << YAML::BeginMap;
  yaml::emit_sonar_spec(out, impl_->spec);
  out << YAML::EndMap;
  if (impl_->noise) {
    fs::create_directories(tmp / "noise");
    write_float_image((tmp / "noise/mean.tiff").string(), impl_->noise->mean);
    write_float_image((tmp / "noise/std.tiff").string(), impl_->noise->std);
    out << YAML::Key << "noise" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "mean" << YAML::Value << "noise/mean.tiff";
    out << YAML::Key << "std" << YAML::Value << "noise/std.tiff";
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  write_text_file((tmp / "sonar.yaml").string(), std::string(out.c_str()) + "\n");
  write_text_file((tmp / "frames.csv").string(), frames_csv_text(impl_->frames));
  write_tum((tmp / "navigation.tum").string(), impl_->navigation);
  impl_->out.commit();
}

}  // namespace sonar3d
