#include "sonar3d/core/atomic_file.hpp"

#include <atomic>
#include <fstream>
#include <sstream>
#include <system_error>
#include <unistd.h>

#include "sonar3d/core/error.hpp"

namespace fs = std::filesystem;

namespace sonar3d {

AtomicPath::AtomicPath(fs::path final_path) : final_(std::move(final_path)) {
  static std::atomic<unsigned> counter{0};
  if (final_.filename().empty()) final_ = final_.parent_path();  // "dir/" -> "dir"
  const fs::path parent = final_.has_parent_path() ? final_.parent_path() : fs::path(".");
  if (!fs::exists(parent)) {
    throw Error("cannot write '" + final_.string() + "': directory '" + parent.string() +
                "' does not exist");
  }
  temp_ = parent / ("." + final_.filename().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
                    std::to_string(counter++));
}

AtomicPath::~AtomicPath() {
  if (!committed_) {
    std::error_code ec;
    fs::remove_all(temp_, ec);  // best effort: never throw from a destructor
  }
}

void AtomicPath::commit() {
  std::error_code ec;
  if (fs::is_directory(final_) && fs::is_directory(temp_)) {
    // rename() cannot replace a non-empty directory: move the old one aside first.
    const fs::path old = temp_.string() + ".old";
    fs::rename(final_, old, ec);
    if (ec) throw Error("cannot replace '" + final_.string() + "': " + ec.message());
    fs::rename(temp_, final_, ec);
    if (ec) {
      fs::rename(old, final_);
      throw Error("cannot write '" + final_.string() + "': " + ec.message());
    }
    fs::remove_all(old, ec);
  } else {
    if (fs::is_directory(final_)) {
      throw Error("cannot write file '" + final_.string() + "': a directory has that name");
    }
    fs::rename(temp_, final_, ec);
    if (ec) throw Error("cannot write '" + final_.string() + "': " + ec.message());
  }
  committed_ = true;
}

void write_text_file(const std::string& path, const std::string& contents) {
  AtomicPath out(path);
  {
    std::ofstream f(out.temp(), std::ios::binary);
    if (!f) throw Error("cannot open '" + path + "' for writing");
    f << contents;
    f.close();
    if (!f) throw Error("failed writing '" + path + "' (disk full?)");
  }
  out.commit();
}

std::string read_text_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error("cannot open '" + path + "' for reading: " +
                      (fs::exists(path) ? "permission denied or not a file" : "no such file"));
  std::ostringstream os;
  os << f.rdbuf();
  return os.str();
}

}  // namespace sonar3d
