#include "sonar3d/core/output_dir.hpp"

#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <memory>
#include <sstream>
#include <system_error>

#include "sonar3d/core/atomic_file.hpp"
#include "sonar3d/core/error.hpp"

namespace fs = std::filesystem;

namespace sonar3d {
namespace {

// `inner` lies strictly inside `outer` (both absolute, normalised).
bool lies_inside(const fs::path& inner, const fs::path& outer) {
  auto i = inner.begin(), o = outer.begin();
  for (; o != outer.end(); ++o, ++i) {
    if (o->empty()) continue;  // a trailing separator
    if (i == inner.end() || *i != *o) return false;
  }
  for (; i != inner.end(); ++i) {
    if (!i->empty()) return true;
  }
  return false;
}

fs::path resolved(const fs::path& p) {
  std::error_code ec;
  fs::path r = fs::weakly_canonical(fs::absolute(p), ec);
  return ec ? fs::absolute(p).lexically_normal() : r;
}

}  // namespace

const char* output_kind_name(OutputKind kind) {
  switch (kind) {
    case OutputKind::Dataset:
      return "dataset";
    case OutputKind::Plan:
      return "plan directory";
    case OutputKind::PointCloud:
      return "point cloud";
    case OutputKind::Mesh:
      return "mesh";
    case OutputKind::GeoTiff:
      return "elevation map";
    case OutputKind::Tiff:
      return "TIFF image";
    case OutputKind::Png:
      return "picture";
    case OutputKind::Gltf:
      return "glTF file";
    case OutputKind::VoxelMap:
      return "voxel map";
    case OutputKind::ReconstructionJson:
      return "reconstruction report";
    case OutputKind::EvaluationJson:
      return "evaluation";
    case OutputKind::RegistrationJson:
      return "registration result";
    case OutputKind::PlacementsJson:
      return "placements file";
    case OutputKind::PlanResultsJson:
      return "plan results (JSON)";
    case OutputKind::PlanResultsCsv:
      return "plan results (CSV)";
    case OutputKind::Survey:
      return "survey directory";
    case OutputKind::Relocalization:
      return "relocalization directory";
  }
  return "output";
}

bool is_directory_kind(OutputKind kind) {
  return kind == OutputKind::Dataset || kind == OutputKind::Plan || kind == OutputKind::Survey ||
         kind == OutputKind::Relocalization;
}

const char* json_format_marker(OutputKind kind) {
  switch (kind) {
    case OutputKind::ReconstructionJson:
      return "sonar3d-reconstruction";
    case OutputKind::EvaluationJson:
      return "sonar3d-evaluation";
    case OutputKind::RegistrationJson:
      return "sonar3d-registration";
    case OutputKind::PlacementsJson:
      return "sonar3d-placements";
    case OutputKind::PlanResultsJson:
      return "sonar3d-plan-results";
    case OutputKind::Survey:
      return "sonar3d-survey";
    case OutputKind::Relocalization:
      return "sonar3d-relocalization";
    default:
      return "";
  }
}

namespace {

constexpr const char* kSoftware = "sonar3d";

std::string read_head(const fs::path& path, std::size_t bytes) {
  std::ifstream f(path, std::ios::binary);
  std::string head(bytes, '\0');
  f.read(head.data(), static_cast<std::streamsize>(bytes));
  head.resize(f ? bytes : static_cast<std::size_t>(std::max<std::streamsize>(0, f.gcount())));
  return head;
}

std::string read_all(const fs::path& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error("cannot open '" + path.string() + "' for reading");
  std::ostringstream os;
  os << f.rdbuf();
  return os.str();
}

void write_all(const fs::path& path, const std::string& bytes) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f << bytes;
  f.close();
  if (!f) throw Error("failed writing '" + path.string() + "' (disk full?)");
}

// Classic TIFF, either byte order: the IFD 0 entries (tag, type, count, value/offset).
struct Tiff {
  bool little = true;
  std::uint32_t ifd = 0;
  std::uint16_t get16(const std::string& b, std::size_t at) const {
    const auto* p = reinterpret_cast<const unsigned char*>(b.data() + at);
    return little ? std::uint16_t(p[0] | p[1] << 8) : std::uint16_t(p[0] << 8 | p[1]);
  }
  std::uint32_t get32(const std::string& b, std::size_t at) const {
    const auto* p = reinterpret_cast<const unsigned char*>(b.data() + at);
    return little ? std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 |
                        std::uint32_t(p[3]) << 24
                  : std::uint32_t(p[3]) | std::uint32_t(p[2]) << 8 | std::uint32_t(p[1]) << 16 |
                        std::uint32_t(p[0]) << 24;
  }
  void put16(std::string& b, std::uint16_t v) const {
    const char c[2] = {char(little ? v & 0xff : v >> 8), char(little ? v >> 8 : v & 0xff)};
    b.append(c, 2);
  }
  void put32(std::string& b, std::uint32_t v) const {
    for (int i = 0; i < 4; ++i) b.push_back(char((v >> (little ? 8 * i : 8 * (3 - i))) & 0xff));
  }
};

bool parse_tiff(const std::string& b, Tiff& t) {
  if (b.size() < 8) return false;
  if (b.compare(0, 2, "II") == 0) {
    t.little = true;
  } else if (b.compare(0, 2, "MM") == 0) {
    t.little = false;
  } else {
    return false;
  }
  if (t.get16(b, 2) != 42) return false;  // 43 = BigTIFF: not written by sonar3d
  t.ifd = t.get32(b, 4);
  return t.ifd + 2 <= b.size() && t.ifd + 2 + 12u * t.get16(b, t.ifd) + 4 <= b.size();
}

// The Software tag (305) of IFD 0, or "" when absent or unreadable.
std::string tiff_software(const std::string& b) {
  Tiff t;
  if (!parse_tiff(b, t)) return "";
  const std::uint16_t n = t.get16(b, t.ifd);
  for (std::uint16_t i = 0; i < n; ++i) {
    const std::size_t e = t.ifd + 2 + 12u * i;
    if (t.get16(b, e) != 305 || t.get16(b, e + 2) != 2) continue;
    const std::uint32_t count = t.get32(b, e + 4);
    const std::size_t at = count <= 4 ? e + 8 : t.get32(b, e + 8);
    if (at + count > b.size()) return "";
    return std::string(b.data() + at, count).c_str();
  }
  return "";
}

bool is_sonar3d_tiff(const fs::path& path) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec || size > (std::uintmax_t{1} << 31)) return false;
  return tiff_software(read_all(path)).rfind(kSoftware, 0) == 0;
}

std::uint32_t crc32(const char* data, std::size_t n) {
  static const std::array<std::uint32_t, 256> table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = c & 1 ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::size_t i = 0; i < n; ++i)
    c = table[(c ^ static_cast<unsigned char>(data[i])) & 0xff] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

std::uint32_t be32(const std::string& b, std::size_t at) {
  const auto* p = reinterpret_cast<const unsigned char*>(b.data() + at);
  return std::uint32_t(p[0]) << 24 | std::uint32_t(p[1]) << 16 | std::uint32_t(p[2]) << 8 | p[3];
}

void put_be32(std::string& b, std::uint32_t v) {
  for (int i = 3; i >= 0; --i) b.push_back(char((v >> (8 * i)) & 0xff));
}

const std::string kPngSignature("\x89PNG\r\n\x1a\n", 8);

// A tEXt "Software" chunk before the image data.
bool is_sonar3d_png(const fs::path& path) {
  const std::string b = read_head(path, 1 << 16);
  if (b.compare(0, 8, kPngSignature) != 0) return false;
  const std::string want = std::string("Software") + '\0' + kSoftware;
  for (std::size_t at = 8; at + 8 <= b.size();) {
    const std::uint32_t len = be32(b, at);
    const std::string type = b.substr(at + 4, 4);
    if (type == "IDAT" || type == "IEND") return false;
    if (type == "tEXt" && at + 8 + len <= b.size() && b.compare(at + 8, want.size(), want) == 0) {
      return true;
    }
    at += 12 + std::size_t{len};
  }
  return false;
}

// The marker is looked for in the first 4 kB, then, for a JSON of up to 64 MB, in the whole file:
// a writer that sorts its keys (nlohmann::json) puts "format" after "candidates" or "catalogue",
// which can fill more than 4 kB (a 3D recognition's placements file).
bool has_json_marker(const fs::path& path, const std::string& marker) {
  const auto found = [&](const std::string& text) {
    return text.find("\"format\": \"" + marker + "\"") != std::string::npos ||
           text.find("\"format\":\"" + marker + "\"") != std::string::npos;
  };
  constexpr std::size_t kHead = 4096;
  constexpr std::uintmax_t kWhole = 64u << 20;
  const std::string head = read_head(path, kHead);
  if (found(head)) return true;
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec || size <= head.size() || size > kWhole) return false;
  const std::size_t first = head.find_first_not_of(" \t\r\n");
  if (first == std::string::npos || (head[first] != '{' && head[first] != '[')) return false;
  return found(read_head(path, static_cast<std::size_t>(size)));
}

bool is_sonar3d_ply_kind(const fs::path& path, bool mesh) {
  const std::string h = read_head(path, 256);
  if (h.rfind("ply\nformat ", 0) != 0) return false;
  const bool cloud =
      h.find("\ncomment sonar3d point cloud, world frame, metres\n") != std::string::npos;
  const bool textured =
      h.find("\ncomment sonar3d textured mesh, world frame, metres") != std::string::npos;
  const bool plain_mesh = h.find("\ncomment sonar3d mesh") != std::string::npos;
  return mesh ? (plain_mesh || textured) : (cloud || textured);
}

}  // namespace

void mark_tiff_as_sonar3d(const fs::path& path) {
  std::string b = read_all(path);
  Tiff t;
  if (!parse_tiff(b, t)) {
    throw Error("cannot mark '" + path.string() + "' as written by sonar3d: not a classic TIFF");
  }
  const std::uint16_t n = t.get16(b, t.ifd);
  std::vector<std::string> entries;
  bool have = false;
  for (std::uint16_t i = 0; i < n; ++i) {
    std::string e = b.substr(t.ifd + 2 + 12u * i, 12);
    if (t.get16(e, 0) == 305) {  // an existing Software tag is replaced
      have = true;
      continue;
    }
    entries.push_back(std::move(e));
  }
  (void)have;
  const std::uint32_t next = t.get32(b, t.ifd + 2 + 12u * n);
  // Word-aligned: the new IFD at the end, then the tag's text.
  if (b.size() % 2) b.push_back('\0');
  const std::uint32_t ifd = static_cast<std::uint32_t>(b.size());
  const std::string text = std::string(kSoftware) + '\0';
  const std::uint32_t text_at = ifd + 2 + 12u * static_cast<std::uint32_t>(entries.size() + 1) + 4;
  std::string tag;
  t.put16(tag, 305);
  t.put16(tag, 2);  // ASCII
  t.put32(tag, static_cast<std::uint32_t>(text.size()));
  t.put32(tag, text_at);
  auto pos = entries.begin();
  while (pos != entries.end() && t.get16(*pos, 0) < 305) ++pos;
  entries.insert(pos, tag);  // entries stay sorted by tag
  std::string out;
  t.put16(out, static_cast<std::uint16_t>(entries.size()));
  for (const auto& e : entries) out += e;
  t.put32(out, next);
  b += out;
  b += text;
  std::string hdr;
  t.put32(hdr, ifd);
  b.replace(4, 4, hdr);
  write_all(path, b);
}

void mark_png_as_sonar3d(const fs::path& path) {
  std::string b = read_all(path);
  if (b.size() < 33 || b.compare(0, 8, kPngSignature) != 0 || b.compare(12, 4, "IHDR") != 0) {
    throw Error("cannot mark '" + path.string() + "' as written by sonar3d: not a PNG");
  }
  const std::size_t after_ihdr = 8 + 12 + be32(b, 8);
  const std::string body = std::string("tEXt") + "Software" + '\0' + kSoftware;
  std::string chunk;
  put_be32(chunk, static_cast<std::uint32_t>(body.size() - 4));
  chunk += body;
  put_be32(chunk, crc32(body.data(), body.size()));
  b.insert(after_ihdr, chunk);
  write_all(path, b);
}

bool is_sonar3d_output(const fs::path& path, OutputKind kind) {
  std::error_code ec;
  if (is_directory_kind(kind)) {
    if (!fs::is_directory(path, ec)) return false;
  } else if (!fs::is_regular_file(path, ec)) {
    return false;
  }
  switch (kind) {
    case OutputKind::Dataset: {
      const fs::path yaml = path / "sonar.yaml";
      if (!fs::is_regular_file(yaml, ec) || fs::file_size(yaml, ec) > (1u << 24)) return false;
      try {
        const YAML::Node root = YAML::LoadFile(yaml.string());
        return root.IsMap() && root["format"] && root["format"].IsScalar() &&
               root["format"].Scalar() == "sonar3d-dataset";
      } catch (const std::exception&) {
        return false;
      }
    }
    case OutputKind::Plan: {
      // points/ and the copy of the sweep; or points/ alone, as another MPI rank may have just
      // created it before rank 0 copies the sweep.
      if (!fs::is_directory(path / "points", ec)) return false;
      if (fs::is_regular_file(path / "sweep.yaml", ec)) return true;
      for (fs::directory_iterator it(path, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string n = it->path().filename().string();
        if (n != "points" && n.rfind('.', 0) != 0) return false;
      }
      return !ec;
    }
    case OutputKind::PointCloud:
      return is_sonar3d_ply_kind(path, false);
    case OutputKind::Mesh:
      return is_sonar3d_ply_kind(path, true);
    case OutputKind::GeoTiff:
    case OutputKind::Tiff:
      return is_sonar3d_tiff(path);
    case OutputKind::Png:
      return is_sonar3d_png(path);
    case OutputKind::Gltf: {  // the JSON chunk of a .glb names its generator
      const std::string b = read_head(path, 20 + 4096);
      return b.size() > 20 && b.compare(0, 4, "glTF") == 0 &&
             b.find("\"generator\":\"sonar3d\"") != std::string::npos;
    }
    case OutputKind::VoxelMap:
      return read_head(path, 1 << 16).find("sonar3d-voxel-map") != std::string::npos;
    case OutputKind::ReconstructionJson:
    case OutputKind::EvaluationJson:
    case OutputKind::RegistrationJson:
    case OutputKind::PlacementsJson:
      return has_json_marker(path, json_format_marker(kind));
    case OutputKind::PlanResultsJson:  // also as written before it had the marker
      return has_json_marker(path, json_format_marker(kind)) ||
             read_head(path, 64).rfind("{\n  \"version\": 1,\n  \"rank_by\":", 0) == 0;
    case OutputKind::PlanResultsCsv:
      return read_head(path, 64).rfind("id,status,rank,", 0) == 0;
    case OutputKind::Survey:  // summary.json, written when the survey starts
      return fs::is_directory(path, ec) && has_json_marker(path / "summary.json", "sonar3d-survey");
    case OutputKind::Relocalization:
      return fs::is_directory(path, ec) &&
             has_json_marker(path / "relocalization.json", "sonar3d-relocalization");
  }
  return false;
}

namespace {

// What sits at `path`, for messages: "a FIFO", "a directory", ...
std::string describe(const fs::file_status& st) {
  switch (st.type()) {
    case fs::file_type::fifo:
      return "a FIFO";
    case fs::file_type::block:
      return "a block device";
    case fs::file_type::character:
      return "a character device";
    case fs::file_type::socket:
      return "a socket";
    case fs::file_type::directory:
      return "a directory";
    case fs::file_type::symlink:
      return "a symbolic link";
    default:
      return "a file";
  }
}

std::string with_article(const std::string& noun) {
  return (std::string("aeiou").find(noun.empty() ? 'x' : noun[0]) != std::string::npos ? "an "
                                                                                       : "a ") +
         noun;
}

// The kind of sonar3d output a file or directory is, if any (for "is a sonar3d X, not a Y").
std::string other_sonar3d_kind(const fs::path& path, OutputKind wanted) {
  for (OutputKind k :
       {OutputKind::Dataset, OutputKind::Plan, OutputKind::PointCloud, OutputKind::Mesh,
        OutputKind::GeoTiff, OutputKind::Png, OutputKind::Gltf, OutputKind::VoxelMap,
        OutputKind::ReconstructionJson, OutputKind::EvaluationJson, OutputKind::RegistrationJson,
        OutputKind::PlacementsJson, OutputKind::PlanResultsJson, OutputKind::PlanResultsCsv,
        OutputKind::Survey, OutputKind::Relocalization}) {
    if (k != wanted && is_sonar3d_output(path, k)) return output_kind_name(k);
  }
  return "";
}

}  // namespace

void check_output_location(const fs::path& path, const OutputPolicy& policy,
                           const std::string& flag, const std::string& what) {
  const std::string in_flag = " (" + flag + ")";
  require(!path.empty(), "no output path given" + in_flag);
  {
    // An output is written under a temporary name next to it (".NAME.tmp-PID-N", and a
    // GeoTIFF's writer again inside that one), which the file system must accept too: the name
    // may take at most half of what the directory allows, less the temporaries' additions.
    const fs::path parent = path.has_parent_path() ? path.parent_path() : fs::path(".");
    long name_max = ::pathconf(parent.c_str(), _PC_NAME_MAX);
    if (name_max <= 0) name_max = 255;
    const std::size_t longest = static_cast<std::size_t>(std::max(16L, (name_max - 64) / 2));
    const std::string name = path.filename().string();
    if (name.size() > longest) {
      throw Error("the output name '" + printable(name, 40) + "'" + in_flag + " is " +
                  std::to_string(name.size()) + " bytes long; with sonar3d's temporary names " +
                  "this file system takes at most " + std::to_string(longest) +
                  ": choose a shorter name");
    }
  }
  const fs::path out = resolved(path);
  std::error_code ec;
  for (const fs::path& src : policy.sources) {
    if (src.empty() || !fs::exists(src, ec)) continue;
    const fs::path in = resolved(src);
    if (in == out || fs::equivalent(src, path, ec)) {
      throw Error("the output '" + path.string() + "'" + in_flag + " is the input '" +
                  src.string() + "': write the " + what + " elsewhere");
    }
    if (lies_inside(out, in)) {
      throw Error("the output '" + path.string() + "'" + in_flag + " lies inside the input '" +
                  src.string() + "': write the " + what + " outside it");
    }
    if (lies_inside(in, out)) {
      throw Error("the input '" + src.string() + "' lies inside the output '" + path.string() +
                  "'" + in_flag + ", which would be replaced: write the " + what + " elsewhere");
    }
  }
  const fs::file_status lst = fs::symlink_status(path, ec);
  if (!fs::exists(lst)) return;
  const fs::file_status st = fs::status(path, ec);
  if (!fs::is_regular_file(st) && !fs::is_directory(st)) {
    throw Error("'" + path.string() + "'" + in_flag + " is " +
                describe(fs::is_symlink(lst) && fs::exists(st) ? st : lst) +
                (fs::is_symlink(lst) ? " (through a symbolic link)" : "") +
                ", not a regular file or directory: sonar3d writes only those; choose another "
                "output");
  }
}

void check_output(const fs::path& path, OutputKind kind, const OutputPolicy& policy,
                  const std::string& flag) {
  const std::string what = output_kind_name(kind);
  const std::string in_flag = " (" + flag + ")";
  check_output_location(path, policy, flag, what);
  std::error_code ec;
  const fs::file_status lst = fs::symlink_status(path, ec);
  if (!fs::exists(lst)) {
    const fs::path parent = path.has_parent_path() ? path.parent_path() : fs::path(".");
    if (!is_directory_kind(kind) && !fs::is_directory(parent, ec)) {
      throw Error("cannot write '" + path.string() + "'" + in_flag + ": directory '" +
                  parent.string() + "' does not exist");
    }
    return;
  }
  const fs::file_status st = fs::status(path, ec);  // a regular file or directory (above)
  if (is_directory_kind(kind)) {
    if (!fs::is_directory(st)) {
      throw Error("'" + path.string() + "'" + in_flag +
                  " exists and is not a directory: sonar3d "
                  "will not replace it; choose another output or remove it yourself");
    }
    if (fs::is_empty(path, ec) && !ec) return;
  } else if (fs::is_directory(st)) {
    throw Error("'" + path.string() + "'" + in_flag + " is a directory, not " + with_article(what) +
                " file: choose a file name");
  }
  if (is_sonar3d_output(path, kind)) {
    if (policy.overwrite) return;
    throw Error("'" + path.string() + "'" + in_flag + " already holds a sonar3d " + what +
                ": pass --overwrite to replace it, or choose another output");
  }
  const std::string other = other_sonar3d_kind(path, kind);
  const std::string why =
      !other.empty() ? "is a sonar3d " + other + ", not " + with_article(what)
      : kind == OutputKind::Dataset
          ? "is not a sonar3d dataset (no sonar.yaml with 'format: sonar3d-dataset')"
          : "is not a sonar3d " + what;
  throw Error("'" + path.string() + "'" + in_flag + " exists and " + why +
              ": sonar3d will not replace it; choose another output or remove it yourself");
}

void check_output_directory(const fs::path& dir, OutputKind kind, const OutputPolicy& policy) {
  check_output(dir, kind, policy, "-o");
}

OutputDirectory::OutputDirectory(fs::path dir, OutputKind kind, const OutputPolicy& policy)
    : final_(std::move(dir)), kind_(kind) {
  if (final_.filename().empty()) final_ = final_.parent_path();  // "dir/" -> "dir"
  notes_ = recover_interrupted_writes(final_);
  if (policy.on_note) {
    for (const auto& n : notes_) policy.on_note(n);
  }
  check_output_directory(final_, kind, policy);
  atomic_ = std::make_unique<AtomicPath>(final_);
  staging_ = atomic_->temp();
}

OutputDirectory::~OutputDirectory() = default;

void OutputDirectory::commit() {
  if (!is_sonar3d_output(staging_, kind_)) {
    throw Error("cannot write '" + final_.string() + "': the new " + output_kind_name(kind_) +
                " is incomplete");
  }
  atomic_->commit();
}

namespace {
std::atomic<unsigned> g_group_counter{0};
}  // namespace

OutputFiles::OutputFiles(OutputPolicy policy) : policy_(std::move(policy)) {}

OutputFiles::~OutputFiles() {
  if (committed_) return;
  std::error_code ec;
  for (const Member& m : members_) fs::remove_all(m.temp, ec);  // best effort, never throws
}

fs::path OutputFiles::add(fs::path final_path, OutputKind kind, const std::string& flag) {
  require(!is_directory_kind(kind), std::string("OutputFiles: ") + output_kind_name(kind) +
                                        " is a directory output (use OutputDirectory)");
  require(!committed_, "OutputFiles: add() after commit()");
  for (const std::string& n : recover_interrupted_writes(final_path)) {
    notes_.push_back(n);
    if (policy_.on_note) policy_.on_note(n);
  }
  const fs::path abs = resolved(final_path);
  for (const Member& m : members_) {
    if (resolved(m.final_path) == abs) {
      throw Error(m.flag + " and " + flag + " name the same file '" + final_path.string() + "'");
    }
  }
  check_output(final_path, kind, policy_, flag);
  const fs::path parent = final_path.has_parent_path() ? final_path.parent_path() : ".";
  // The final extension kept last: writers choose the encoder by it.
  const fs::path temp =
      parent / ("." + final_path.filename().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
                std::to_string(g_group_counter++) + final_path.extension().string());
  members_.push_back({std::move(final_path), temp, kind, flag});
  return temp;
}

void OutputFiles::commit(const std::function<void(std::size_t)>& after_rename) {
  require(!committed_, "OutputFiles: commit() twice");
  std::error_code ec;
  for (const Member& m : members_) {
    if (!fs::is_regular_file(m.temp, ec)) {
      throw Error("cannot write '" + m.final_path.string() + "': the new " +
                  output_kind_name(m.kind) + " was not written");
    }
    // The rule again, on the outputs as they are now (another process may have been quicker).
    check_output(m.final_path, m.kind, policy_, m.flag);
    sync_path(m.temp);
  }
  const std::string tag = std::to_string(::getpid()) + "-" + std::to_string(g_group_counter++);
  std::vector<GroupJournalEntry> entries;
  std::vector<fs::path> journals;
  for (const Member& m : members_) {
    const fs::path parent = m.final_path.has_parent_path() ? m.final_path.parent_path() : ".";
    const std::string name = m.final_path.filename().string();
    GroupJournalEntry e{m.final_path, m.temp, {}};
    if (fs::exists(fs::symlink_status(m.final_path, ec))) {
      e.backup = parent / ("." + name + ".backup-" + tag);
    }
    entries.push_back(e);
    journals.push_back(parent / ("." + name + ".group-" + tag));
  }
  const bool single = members_.size() == 1;
  if (!single) {
    // Journals first (complete and on disk before anything is renamed).
    const std::string text = group_journal_text(entries, journals);
    for (const fs::path& j : journals) {
      write_all(j, text);
      sync_path(j);
    }
    for (const fs::path& j : journals) sync_path(j.has_parent_path() ? j.parent_path() : ".");
  }
  auto undo = [&](std::size_t renamed) {
    std::error_code e2;
    for (std::size_t i = 0; i < renamed; ++i) fs::remove(entries[i].final_path, e2);
    for (const auto& e : entries) {
      if (!e.backup.empty() && fs::exists(fs::symlink_status(e.backup, e2))) {
        fs::rename(e.backup, e.final_path, e2);
      }
    }
    for (const fs::path& j : journals) fs::remove(j, e2);
  };
  for (std::size_t i = 0; i < entries.size(); ++i) {
    if (single || entries[i].backup.empty()) continue;
    fs::rename(entries[i].final_path, entries[i].backup, ec);
    if (ec) {
      const std::string msg = ec.message();
      undo(0);
      throw Error("cannot replace '" + entries[i].final_path.string() + "': " + msg);
    }
  }
  for (std::size_t i = 0; i < entries.size(); ++i) {
    fs::rename(entries[i].temp, entries[i].final_path, ec);  // a single file: replaces atomically
    if (ec) {
      const std::string msg = ec.message();
      if (!single) undo(i);
      throw Error("cannot write '" + entries[i].final_path.string() + "': " + msg);
    }
    if (after_rename) after_rename(i);
  }
  committed_ = true;
  for (const auto& e : entries) {
    sync_path(e.final_path.has_parent_path() ? e.final_path.parent_path() : ".");
  }
  for (const fs::path& j : journals) fs::remove(j, ec);  // the set is complete
  for (const auto& e : entries) {
    if (!e.backup.empty()) fs::remove(e.backup, ec);
  }
}

}  // namespace sonar3d
