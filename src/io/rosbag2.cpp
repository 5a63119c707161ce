// ROS 2 bags in the sqlite3 storage (rosbag2_storage_default_plugins): metadata.yaml beside one
// or more .db3 files holding the tables topics(id, name, type, serialization_format,
// offered_qos_profiles) and messages(id, topic_id, timestamp, data).
#include <sqlite3.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>

#include "rosbag_internal.hpp"
#include "sonar3d/core/error.hpp"
#include "sonar3d/io/yaml_config.hpp"

namespace fs = std::filesystem;

namespace sonar3d::bag {
namespace {

struct Db {
  sqlite3* db = nullptr;
  ~Db() {
    if (db) sqlite3_close(db);
  }
};

struct Stmt {
  sqlite3_stmt* s = nullptr;
  ~Stmt() {
    if (s) sqlite3_finalize(s);
  }
};

std::string sql_error(sqlite3* db) { return db ? sqlite3_errmsg(db) : "out of memory"; }

bool has_sqlite_magic(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  char magic[16] = {};
  f.read(magic, sizeof magic);
  return f.gcount() == 16 && std::memcmp(magic, "SQLite format 3", 16) == 0;
}

void open_db(const fs::path& file, Db& d) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) {
    throw Error("cannot read ROS 2 bag file '" + file.string() + "': not a regular file");
  }
  if (!has_sqlite_magic(file)) {
    throw Error(file.string() +
                ": not an sqlite3 database (no 'SQLite format 3' signature at "
                "offset 0); ROS 2 bags in other storages (MCAP) must be converted with "
                "`ros2 bag convert` to sqlite3");
  }
  if (sqlite3_open_v2(file.c_str(), &d.db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
    throw Error(file.string() + ": cannot open the sqlite3 database: " + sql_error(d.db));
  }
  // Hostile files: no schema tricks, and no value longer than the file itself.
  sqlite3_db_config(d.db, SQLITE_DBCONFIG_DEFENSIVE, 1, nullptr);
  sqlite3_db_config(d.db, SQLITE_DBCONFIG_TRUSTED_SCHEMA, 0, nullptr);
  const auto size = fs::file_size(file, ec);
  sqlite3_limit(d.db, SQLITE_LIMIT_LENGTH,
                static_cast<int>(std::min<std::uintmax_t>(size + 1, 1u << 30)));
}

void prepare(const Db& d, const fs::path& file, const char* sql, Stmt& st) {
  if (sqlite3_prepare_v2(d.db, sql, -1, &st.s, nullptr) != SQLITE_OK) {
    throw Error(file.string() + ": not a ROS 2 bag database (" + sql_error(d.db) + ")");
  }
}

std::string text(sqlite3_stmt* s, int col) {
  const unsigned char* t = sqlite3_column_text(s, col);
  return t ? std::string(reinterpret_cast<const char*>(t)) : std::string();
}

class Ros2Bag : public BagReader {
 public:
  explicit Ros2Bag(const fs::path& bag) {
    std::error_code ec;
    if (fs::is_directory(bag, ec)) {
      const fs::path meta = bag / "metadata.yaml";
      if (fs::exists(meta, ec)) {
        read_metadata(bag, meta);
      } else {
        for (const auto& e : fs::directory_iterator(bag, ec)) {
          if (e.path().extension() == ".db3") files_.push_back(e.path());
        }
        std::sort(files_.begin(), files_.end());
      }
      if (files_.empty()) {
        throw Error("'" + bag.string() +
                    "' is not a ROS 2 bag: no .db3 file and no metadata.yaml "
                    "naming one");
      }
    } else {
      files_.push_back(bag);
    }
    for (std::size_t f = 0; f < files_.size(); ++f) scan(f);
  }
  const std::vector<BagTopic>& topics() const override { return topics_; }
  RosWire wire() const override { return RosWire::Cdr; }
  std::string format() const override { return "ROS 2 (sqlite3)"; }

  void read(const std::string& topic, const Visitor& fn) const override {
    const BagTopic* t = find(topic);
    if (!t) throw Error("no topic '" + topic + "' in the bag");
    std::size_t number = 0;
    for (std::size_t f = 0; f < files_.size(); ++f) {
      const auto it = ids_[f].find(topic);
      if (it == ids_[f].end()) continue;
      Db d;
      open_db(files_[f], d);
      Stmt st;
      prepare(d, files_[f],
              "SELECT timestamp, data FROM messages WHERE topic_id = ? ORDER BY timestamp, id", st);
      sqlite3_bind_int64(st.s, 1, it->second);
      int rc;
      while ((rc = sqlite3_step(st.s)) == SQLITE_ROW) {
        const std::int64_t ts = sqlite3_column_int64(st.s, 0);
        const void* blob = sqlite3_column_blob(st.s, 1);
        const int n = sqlite3_column_bytes(st.s, 1);
        const std::string where = files_[f].string() + ": " + topic + " message " +
                                  std::to_string(number) + " (t = " + std::to_string(ts) + " ns)";
        fn(ts, static_cast<const std::uint8_t*>(blob), static_cast<std::size_t>(n), where);
        ++number;
      }
      if (rc != SQLITE_DONE) {
        throw Error(files_[f].string() + ": reading " + topic + " message " +
                    std::to_string(number) + ": " + sql_error(d.db));
      }
    }
  }

 private:
  void read_metadata(const fs::path& dir, const fs::path& meta) {
    const YAML::Node root = yaml::load_file(meta.string());
    const YAML::Node info = root.IsMap() ? root["rosbag2_bagfile_information"] : YAML::Node();
    if (!info || !info.IsMap()) {
      throw Error(meta.string() + ": no 'rosbag2_bagfile_information' mapping");
    }
    const std::string storage =
        yaml::get_string(info, "storage_identifier", "sqlite3", meta.string());
    if (storage != "sqlite3") {
      throw Error(meta.string() + ": storage '" + printable(storage) +
                  "' is not read; convert the bag with `ros2 bag convert` to sqlite3");
    }
    const std::string comp = yaml::get_string(info, "compression_format", "", meta.string());
    if (!comp.empty()) {
      throw Error(meta.string() + ": compressed bags ('" + printable(comp) +
                  "') are not read; decompress with `ros2 bag decompress` or `ros2 bag convert`");
    }
    const YAML::Node paths = info["relative_file_paths"];
    if (!paths || !paths.IsSequence()) {
      throw Error(meta.string() + ": 'relative_file_paths' must be a list of .db3 files");
    }
    for (const auto& p : paths) {
      if (!p.IsScalar()) throw Error(meta.string() + ": a relative_file_paths entry is not a name");
      const fs::path rel = p.Scalar();
      if (rel.empty() || rel.is_absolute() || rel.has_parent_path()) {
        // A bag names its own files; anything else would read outside it.
        throw Error(meta.string() + ": relative_file_paths entry '" + printable(rel.string()) +
                    "' is not a file name inside the bag");
      }
      files_.push_back(dir / rel);
    }
  }

  void scan(std::size_t f) {
    const fs::path& file = files_[f];
    Db d;
    open_db(file, d);
    std::map<std::string, std::int64_t> ids;
    std::map<std::int64_t, std::string> names;
    {
      Stmt st;
      prepare(d, file, "SELECT id, name, type, serialization_format FROM topics", st);
      int rc;
      while ((rc = sqlite3_step(st.s)) == SQLITE_ROW) {
        const std::int64_t id = sqlite3_column_int64(st.s, 0);
        const std::string name = text(st.s, 1), type = text(st.s, 2), ser = text(st.s, 3);
        if (ser != "cdr") {
          throw Error(file.string() + ": topic '" + printable(name) + "' is serialised as '" +
                      printable(ser) + "', not cdr");
        }
        ids[name] = id;
        names[id] = name;
        BagTopic* t = const_cast<BagTopic*>(find(name));
        if (!t) {
          topics_.push_back({name, type, 0});
        } else if (t->type != type) {
          throw Error(file.string() + ": topic '" + printable(name) + "' changes type from " +
                      t->type + " to " + printable(type));
        }
      }
      if (rc != SQLITE_DONE) throw Error(file.string() + ": reading topics: " + sql_error(d.db));
    }
    Stmt st;
    prepare(d, file, "SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id", st);
    int rc;
    while ((rc = sqlite3_step(st.s)) == SQLITE_ROW) {
      const auto it = names.find(sqlite3_column_int64(st.s, 0));
      if (it == names.end()) continue;
      const_cast<BagTopic*>(find(it->second))->messages +=
          static_cast<std::size_t>(sqlite3_column_int64(st.s, 1));
    }
    if (rc != SQLITE_DONE) throw Error(file.string() + ": reading messages: " + sql_error(d.db));
    ids_.push_back(std::move(ids));
  }

  std::vector<fs::path> files_;
  std::vector<std::map<std::string, std::int64_t>> ids_;  // per file: topic name -> id
  std::vector<BagTopic> topics_;
};

void exec(sqlite3* db, const fs::path& file, const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    const std::string e = err ? err : "unknown error";
    sqlite3_free(err);
    throw Error(file.string() + ": " + e);
  }
}

std::string qos_yaml(bool latched) {
  // rosbag2's offered_qos_profiles: reliability 1 = reliable, durability 1 = transient local
  // (what /tf_static needs on replay), 2 = volatile; history 3 = unknown, as recorders write.
  std::ostringstream os;
  os << "- history: 3\n  depth: 0\n  reliability: 1\n  durability: " << (latched ? 1 : 2)
     << "\n  deadline:\n    sec: 2147483647\n    nsec: 4294967295\n  lifespan:\n    sec: "
        "2147483647\n    nsec: 4294967295\n  liveliness: 1\n  liveliness_lease_duration:\n    "
        "sec: 2147483647\n    nsec: 4294967295\n  avoid_ros_namespace_conventions: false";
  return os.str();
}

std::string yaml_quote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out + "\"";
}

}  // namespace

std::unique_ptr<BagReader> open_ros2(const fs::path& bag) { return std::make_unique<Ros2Bag>(bag); }

void write_ros2(const fs::path& dir, const std::string& name, const std::vector<OutTopic>& topics,
                const NextMessage& next) {
  std::int64_t t0 = 0, t1 = 0;
  std::size_t total = 0;
  std::vector<std::size_t> counts(topics.size(), 0);
  fs::create_directories(dir);
  const std::string dbname = (name.empty() ? std::string("bag") : name) + "_0.db3";
  const fs::path file = dir / dbname;
  {
    Db d;
    if (sqlite3_open_v2(file.c_str(), &d.db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr) !=
        SQLITE_OK) {
      throw Error(file.string() + ": cannot create the sqlite3 database: " + sql_error(d.db));
    }
    exec(d.db, file, "PRAGMA journal_mode=MEMORY; PRAGMA synchronous=OFF; BEGIN;");
    exec(d.db, file,
         "CREATE TABLE schema(schema_version INTEGER PRIMARY KEY,ros_distro TEXT NOT NULL);"
         "INSERT INTO schema VALUES(3,'humble');"
         "CREATE TABLE metadata(id INTEGER PRIMARY KEY,metadata_version INTEGER NOT NULL,"
         "metadata TEXT NOT NULL);"
         "CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT NULL,"
         "serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL);"
         "CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT NULL,"
         "timestamp INTEGER NOT NULL, data BLOB NOT NULL);"
         "CREATE INDEX timestamp_idx ON messages (timestamp ASC);");
    {
      Stmt st;
      if (sqlite3_prepare_v2(d.db, "INSERT INTO topics VALUES(?,?,?,'cdr',?)", -1, &st.s,
                             nullptr) != SQLITE_OK) {
        throw Error(file.string() + ": " + sql_error(d.db));
      }
      for (std::size_t k = 0; k < topics.size(); ++k) {
        const std::string qos = qos_yaml(topics[k].latched);
        sqlite3_bind_int64(st.s, 1, static_cast<sqlite3_int64>(k + 1));
        sqlite3_bind_text(st.s, 2, topics[k].name.c_str(), -1, SQLITE_TRANSIENT);
        sqlite3_bind_text(st.s, 3, topics[k].type.c_str(), -1, SQLITE_TRANSIENT);
        sqlite3_bind_text(st.s, 4, qos.c_str(), -1, SQLITE_TRANSIENT);
        if (sqlite3_step(st.s) != SQLITE_DONE) throw Error(file.string() + ": " + sql_error(d.db));
        sqlite3_reset(st.s);
      }
    }
    Stmt st;
    if (sqlite3_prepare_v2(d.db, "INSERT INTO messages(topic_id,timestamp,data) VALUES(?,?,?)", -1,
                           &st.s, nullptr) != SQLITE_OK) {
      throw Error(file.string() + ": " + sql_error(d.db));
    }
    OutMessage m;
    while (next(m)) {
      if (m.topic < 0 || static_cast<std::size_t>(m.topic) >= topics.size()) {
        throw Error(file.string() + ": a message names topic " + std::to_string(m.topic));
      }
      sqlite3_bind_int64(st.s, 1, m.topic + 1);
      sqlite3_bind_int64(st.s, 2, m.time_ns);
      sqlite3_bind_blob(st.s, 3, m.data.data(), static_cast<int>(m.data.size()), SQLITE_STATIC);
      if (sqlite3_step(st.s) != SQLITE_DONE) throw Error(file.string() + ": " + sql_error(d.db));
      sqlite3_reset(st.s);
      if (total == 0 || m.time_ns < t0) t0 = m.time_ns;
      if (total == 0 || m.time_ns > t1) t1 = m.time_ns;
      ++counts[m.topic];
      ++total;
    }
    exec(d.db, file, "COMMIT;");
  }
  std::ostringstream y;
  y << "# written by sonar3d export rosbag\n"
    << "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n"
    << "  duration:\n    nanoseconds: " << (t1 - t0) << "\n"
    << "  starting_time:\n    nanoseconds_since_epoch: " << t0 << "\n"
    << "  message_count: " << total << "\n  topics_with_message_count:\n";
  for (std::size_t k = 0; k < topics.size(); ++k) {
    y << "    - topic_metadata:\n        name: " << topics[k].name
      << "\n        type: " << topics[k].type
      << "\n        serialization_format: cdr\n        offered_qos_profiles: "
      << yaml_quote(qos_yaml(topics[k].latched)) << "\n      message_count: " << counts[k] << "\n";
  }
  y << "  compression_format: \"\"\n  compression_mode: \"\"\n  relative_file_paths:\n    - "
    << dbname << "\n  files:\n    - path: " << dbname
    << "\n      starting_time:\n        nanoseconds_since_epoch: " << t0
    << "\n      duration:\n        nanoseconds: " << (t1 - t0) << "\n      message_count: " << total
    << "\n";
  std::ofstream f(dir / "metadata.yaml");
  f << y.str();
  f.flush();
  if (!f) throw Error((dir / "metadata.yaml").string() + ": write failed");
}

}  // namespace sonar3d::bag
