#include "sonar3d/core/output_dir.hpp"

#include <yaml-cpp/yaml.h>

#include <memory>
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
  }
  return "output";
}

bool is_sonar3d_output(const fs::path& dir, OutputKind kind) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return false;
  switch (kind) {
    case OutputKind::Dataset: {
      const fs::path yaml = dir / "sonar.yaml";
      if (!fs::is_regular_file(yaml, ec) || fs::file_size(yaml, ec) > (1u << 24)) return false;
      try {
        const YAML::Node root = YAML::LoadFile(yaml.string());
        return root.IsMap() && root["format"] && root["format"].IsScalar() &&
               root["format"].Scalar() == "sonar3d-dataset";
      } catch (const std::exception&) {
        return false;
      }
    }
  }
  return false;
}

void check_output_directory(const fs::path& dir, OutputKind kind, const OutputPolicy& policy) {
  const std::string what = output_kind_name(kind);
  const fs::path out = resolved(dir);
  std::error_code ec;
  for (const fs::path& src : policy.sources) {
    if (src.empty() || !fs::exists(src, ec)) continue;
    const fs::path in = resolved(src);
    if (in == out) {
      throw Error("the output '" + dir.string() + "' is the input '" + src.string() +
                  "': write the " + what + " to another directory (-o)");
    }
    if (lies_inside(out, in)) {
      throw Error("the output '" + dir.string() + "' lies inside the input '" + src.string() +
                  "': write the " + what + " outside it (-o)");
    }
    if (lies_inside(in, out)) {
      throw Error("the input '" + src.string() + "' lies inside the output '" + dir.string() +
                  "', which would be replaced: write the " + what + " to another directory (-o)");
    }
  }
  const fs::file_status st = fs::symlink_status(dir, ec);
  if (!fs::exists(st)) return;
  if (!fs::is_directory(dir, ec)) {
    throw Error("'" + dir.string() + "' exists and is not a directory: sonar3d will not replace " +
                "it; choose another output (-o) or remove it yourself");
  }
  if (fs::is_empty(dir, ec) && !ec) return;
  if (is_sonar3d_output(dir, kind)) {
    if (policy.overwrite) return;
    throw Error("'" + dir.string() + "' already holds a sonar3d " + what +
                ": pass --overwrite to replace it, or choose another output (-o)");
  }
  throw Error("'" + dir.string() + "' exists and is not a sonar3d " + what + " (" +
              (kind == OutputKind::Dataset ? "no sonar.yaml with 'format: sonar3d-dataset'"
                                           : "not recognised") +
              "): sonar3d will not replace it; choose another output (-o) or remove it yourself");
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

}  // namespace sonar3d
