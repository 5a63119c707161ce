// ROS 1 bags, format 2.0 (wiki.ros.org/Bags/Format/2.0), read by hand: "#ROSBAG V2.0\n", then
// records of <header_len><header: len-prefixed name=value fields><data_len><data>. Op codes:
// 0x03 bag header, 0x05 chunk (records inside, compression none/bz2/lz4), 0x07 connection,
// 0x02 message data, 0x04 index data, 0x06 chunk info. We scan the records in file order (so an
// unindexed bag, left by an interrupted recording, reads too) and ignore the index.
//
// Why by hand: Debian's librosbag-storage-dev pulls roscpp_serialization, console_bridge,
// Boost and ROS's own lz4 wrapper for what is a documented 6-record format; libbz2 and liblz4
// (both already on every Debian machine) decompress chunks.
#include <bzlib.h>
#include <fcntl.h>
#include <lz4frame.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <climits>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>

#include "binary.hpp"
#include "rosbag_internal.hpp"
#include "sonar3d/core/error.hpp"

namespace fs = std::filesystem;

namespace sonar3d::bag {
namespace {

constexpr char kMagic[] = "#ROSBAG V2.0\n";
constexpr std::size_t kMagicLen = 13;
// A chunk decompresses into memory: the recorder's default chunk is 768 KB and one message rarely
// exceeds a few MB; a larger claim is a hostile or broken file.
constexpr std::uint32_t kMaxChunkBytes = 256u << 20;

enum Op : std::uint8_t {
  kMsgData = 0x02,
  kBagHeader = 0x03,
  kIndexData = 0x04,
  kChunk = 0x05,
  kChunkInfo = 0x06,
  kConnection = 0x07
};

using Fields = std::map<std::string, std::string>;

// Parses a record header (name=value fields, each prefixed by its uint32 length).
Fields parse_fields(const std::uint8_t* p, std::size_t n, const std::string& where) {
  Fields f;
  std::size_t pos = 0;
  while (pos < n) {
    if (n - pos < 4) throw Error(where + ": a header field length is cut");
    const std::uint32_t len = bin::load<std::uint32_t>(p + pos);
    pos += 4;
    if (len > n - pos) {
      throw Error(where + ": a header field of " + std::to_string(len) + " bytes overruns the " +
                  std::to_string(n) + "-byte header");
    }
    const char* s = reinterpret_cast<const char*>(p + pos);
    const void* eq = std::memchr(s, '=', len);
    if (!eq) throw Error(where + ": a header field has no '='");
    const std::size_t k = static_cast<const char*>(eq) - s;
    f[std::string(s, k)] = std::string(s + k + 1, len - k - 1);
    pos += len;
  }
  return f;
}

template <class T>
T field(const Fields& f, const char* name, const std::string& where) {
  const auto it = f.find(name);
  if (it == f.end() || it->second.size() != sizeof(T)) {
    throw Error(where + ": the record header lacks a " + std::to_string(sizeof(T)) +
                "-byte field '" + name + "'");
  }
  return bin::load<T>(reinterpret_cast<const std::uint8_t*>(it->second.data()));
}

std::string sfield(const Fields& f, const char* name, const std::string& where) {
  const auto it = f.find(name);
  if (it == f.end()) throw Error(where + ": the record header lacks the field '" + name + "'");
  return it->second;
}

struct Connection {
  std::string topic, type;
};

// Walks the records of a buffer (the inside of a chunk) or of the file.
struct Record {
  std::uint8_t op = 0;
  Fields fields;
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
  std::uint64_t offset = 0;  // in the file (for a record inside a chunk: the chunk's offset)
};

class Ros1Bag : public BagReader {
 public:
  explicit Ros1Bag(const fs::path& path) : path_(path) {
    // Mapped, not read: a bag can be many GB and we touch each byte once per scan. The mapping
    // is a member with its own destructor, so a constructor that throws (any bad bag) unmaps.
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw Error("cannot open ROS 1 bag '" + path.string() + "'");
    struct stat st {};
    if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
      ::close(fd);
      throw Error("cannot read ROS 1 bag '" + path.string() + "': not a regular file");
    }
    const auto size = static_cast<std::size_t>(st.st_size);
    if (size > 0) {
      void* m = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE, fd, 0);
      if (m == MAP_FAILED) {
        ::close(fd);
        throw Error("cannot map ROS 1 bag '" + path.string() + "'");
      }
      mapping_.p = static_cast<const std::uint8_t*>(m);
      mapping_.n = size;
    }
    ::close(fd);
    map_ = mapping_.p;
    size_ = mapping_.n;
    if (size_ < kMagicLen || std::memcmp(map_, kMagic, kMagicLen) != 0) {
      throw Error(path.string() + ": not a ROS 1 bag v2.0 (no '#ROSBAG V2.0' line at offset 0)");
    }
    std::map<std::uint32_t, std::size_t> counts;
    bool saw_header = false;
    scan([&](const Record& r, const std::string& where) {
      if (r.op == kBagHeader) saw_header = true;
      if (r.op == kConnection) add_connection(r, where);
      if (r.op == kMsgData) ++counts[field<std::uint32_t>(r.fields, "conn", where)];
    });
    if (!saw_header) throw Error(path.string() + ": no bag header record");
    for (const auto& [id, c] : conns_) {
      BagTopic* t = nullptr;
      for (auto& x : topics_) {
        if (x.name == c.topic) t = &x;
      }
      if (!t) {
        topics_.push_back({c.topic, c.type, 0});
        t = &topics_.back();
      } else if (t->type != c.type) {
        throw Error(path.string() + ": topic '" + printable(c.topic) +
                    "' has connections of two "
                    "types (" +
                    t->type + ", " + printable(c.type) + ")");
      }
      t->messages += counts[id];
    }
  }
  Ros1Bag(const Ros1Bag&) = delete;
  Ros1Bag& operator=(const Ros1Bag&) = delete;
  const std::vector<BagTopic>& topics() const override { return topics_; }
  RosWire wire() const override { return RosWire::Ros1; }
  std::string format() const override { return "ROS 1 (v2.0)"; }

  void read(const std::string& topic, const Visitor& fn) const override {
    if (!find(topic)) throw Error("no topic '" + topic + "' in the bag");
    Ros1Bag& self = const_cast<Ros1Bag&>(*this);
    // Messages of one topic usually come in time order: then they stream straight from the map
    // (or the current chunk) to `fn`. Otherwise they are copied and sorted first.
    auto time_of = [](const Record& r, const std::string& where) {
      const auto time = field<std::uint64_t>(r.fields, "time", where);
      return static_cast<std::int64_t>(time & 0xffffffffu) * 1000000000LL +
             static_cast<std::int64_t>(time >> 32);
    };
    auto of_topic = [&](const Record& r, const std::string& where) {
      if (r.op != kMsgData) return false;
      const auto id = field<std::uint32_t>(r.fields, "conn", where);
      const auto it = conns_.find(id);
      if (it == conns_.end()) {
        throw Error(where + ": a message of connection " + std::to_string(id) +
                    " comes before (or without) its connection record");
      }
      return it->second.topic == topic;
    };
    bool sorted = true;
    std::int64_t last = INT64_MIN;
    self.scan([&](const Record& r, const std::string& where) {
      if (!of_topic(r, where)) return;
      const std::int64_t t = time_of(r, where);
      sorted = sorted && t >= last;
      last = t;
    });
    std::size_t number = 0;
    if (sorted) {
      self.scan([&](const Record& r, const std::string& where) {
        if (!of_topic(r, where)) return;
        fn(time_of(r, where), r.data, r.size,
           where + ": " + topic + " message " + std::to_string(number++));
      });
      return;
    }
    struct Item {
      std::int64_t t;
      std::vector<std::uint8_t> data;
      std::string where;
    };
    std::vector<Item> items;
    self.scan([&](const Record& r, const std::string& where) {
      if (!of_topic(r, where)) return;
      items.push_back({time_of(r, where), std::vector<std::uint8_t>(r.data, r.data + r.size),
                       where + ": " + topic + " message " + std::to_string(number++)});
    });
    std::stable_sort(items.begin(), items.end(),
                     [](const Item& a, const Item& b) { return a.t < b.t; });
    for (const Item& i : items) fn(i.t, i.data.data(), i.data.size(), i.where);
  }

 private:
  void add_connection(const Record& r, const std::string& where) {
    const auto id = field<std::uint32_t>(r.fields, "conn", where);
    const Fields h = parse_fields(r.data, r.size, where + " (connection header)");
    Connection c;
    c.topic = sfield(r.fields, "topic", where);
    c.type = sfield(h, "type", where + " (connection header)");
    const auto it = conns_.find(id);
    if (it != conns_.end() && (it->second.topic != c.topic || it->second.type != c.type)) {
      throw Error(where + ": connection " + std::to_string(id) + " is declared twice differently");
    }
    conns_[id] = c;
  }

  // Calls fn for every record of the file, and for every record inside every chunk.
  template <class F>
  void scan(F&& fn) {
    std::size_t pos = kMagicLen;
    std::vector<std::uint8_t> chunk;
    while (pos < size_) {
      const std::string where = path_.string() + " (offset " + std::to_string(pos) + ")";
      Record r = next(map_, size_, pos, where);
      r.offset = pos;
      pos = static_cast<std::size_t>(r.data - map_) + r.size;
      if (r.op == kChunk) {
        const std::string comp = sfield(r.fields, "compression", where);
        const auto usize = field<std::uint32_t>(r.fields, "size", where);
        decompress(comp, r.data, r.size, usize, chunk, where);
        std::size_t q = 0;
        while (q < chunk.size()) {
          const std::string w = where + " chunk byte " + std::to_string(q);
          const std::size_t start = q;
          Record in = next(chunk.data(), chunk.size(), q, w);
          in.offset = r.offset;
          q = start + (in.data - (chunk.data() + start)) + in.size;
          if (in.op == kChunk) throw Error(w + ": a chunk inside a chunk");
          fn(in, w);
        }
      } else {
        fn(r, where);
      }
    }
  }

  static Record next(const std::uint8_t* base, std::size_t n, std::size_t pos,
                     const std::string& where) {
    Record r;
    if (n - pos < 4) throw Error(where + ": the record is cut (the file is truncated)");
    const std::uint32_t hlen = bin::load<std::uint32_t>(base + pos);
    if (hlen > n - pos - 4) {
      throw Error(where + ": a record header of " + std::to_string(hlen) +
                  " bytes runs past the end (the file is truncated or corrupt)");
    }
    r.fields = parse_fields(base + pos + 4, hlen, where);
    const std::size_t dpos = pos + 4 + hlen;
    if (n - dpos < 4) throw Error(where + ": the record's data length is cut (truncated)");
    const std::uint32_t dlen = bin::load<std::uint32_t>(base + dpos);
    if (dlen > n - dpos - 4) {
      throw Error(where + ": record data of " + std::to_string(dlen) +
                  " bytes runs past the end (the file is truncated or corrupt)");
    }
    const auto it = r.fields.find("op");
    if (it == r.fields.end() || it->second.size() != 1) {
      throw Error(where + ": a record without its 'op' field");
    }
    r.op = static_cast<std::uint8_t>(it->second[0]);
    r.data = base + dpos + 4;
    r.size = dlen;
    return r;
  }

  static void decompress(const std::string& comp, const std::uint8_t* p, std::size_t n,
                         std::uint32_t usize, std::vector<std::uint8_t>& out,
                         const std::string& where) {
    if (usize > kMaxChunkBytes) {
      throw Error(where + ": a chunk claims " + std::to_string(usize) +
                  " bytes uncompressed, beyond the 256 MB a chunk may hold");
    }
    if (comp == "none") {
      if (usize != n) {
        throw Error(where + ": an uncompressed chunk of " + std::to_string(n) +
                    " bytes claims size " + std::to_string(usize));
      }
      out.assign(p, p + n);
      return;
    }
    out.resize(usize);
    if (comp == "bz2") {
      unsigned int got = usize;
      const int rc = BZ2_bzBuffToBuffDecompress(reinterpret_cast<char*>(out.data()), &got,
                                                const_cast<char*>(reinterpret_cast<const char*>(p)),
                                                static_cast<unsigned>(n), 0, 0);
      if (rc != BZ_OK || got != usize) {
        throw Error(where + ": the bz2 chunk does not decompress to its " + std::to_string(usize) +
                    " bytes (bzip2 error " + std::to_string(rc) + ")");
      }
      return;
    }
    if (comp == "lz4") {
      LZ4F_dctx* ctx = nullptr;
      if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION))) {
        throw Error(where + ": cannot start lz4");
      }
      std::size_t in = n, outn = usize;
      const std::size_t rc = LZ4F_decompress(ctx, out.data(), &outn, p, &in, nullptr);
      LZ4F_freeDecompressionContext(ctx);
      if (LZ4F_isError(rc) || outn != usize) {
        throw Error(
            where + ": the lz4 chunk does not decompress to its " + std::to_string(usize) +
            " bytes" +
            (LZ4F_isError(rc) ? std::string(" (") + LZ4F_getErrorName(rc) + ")" : std::string()));
      }
      return;
    }
    throw Error(where + ": chunk compression '" + printable(comp) + "' (none, bz2, lz4 are read)");
  }

  struct Mapping {
    const std::uint8_t* p = nullptr;
    std::size_t n = 0;
    Mapping() = default;
    Mapping(const Mapping&) = delete;
    Mapping& operator=(const Mapping&) = delete;
    ~Mapping() {
      if (p) ::munmap(const_cast<std::uint8_t*>(p), n);
    }
  };
  fs::path path_;
  Mapping mapping_;
  const std::uint8_t* map_ = nullptr;
  std::size_t size_ = 0;
  std::map<std::uint32_t, Connection> conns_;
  std::vector<BagTopic> topics_;
};

// ------------------------------------------------------------------------------------ writing

void put_field(std::vector<std::uint8_t>& h, const std::string& name, const void* v,
               std::size_t n) {
  bin::append<std::uint32_t>(h, static_cast<std::uint32_t>(name.size() + 1 + n));
  bin::append_bytes(h, name.data(), name.size());
  h.push_back('=');
  bin::append_bytes(h, v, n);
}
void put_field(std::vector<std::uint8_t>& h, const std::string& name, const std::string& v) {
  put_field(h, name, v.data(), v.size());
}
template <class T>
void put_field_t(std::vector<std::uint8_t>& h, const std::string& name, T v) {
  put_field(h, name, &v, sizeof v);
}

void put_record(std::vector<std::uint8_t>& out, const std::vector<std::uint8_t>& header,
                const std::uint8_t* data, std::size_t n) {
  bin::append<std::uint32_t>(out, static_cast<std::uint32_t>(header.size()));
  out.insert(out.end(), header.begin(), header.end());
  bin::append<std::uint32_t>(out, static_cast<std::uint32_t>(n));
  bin::append_bytes(out, data, n);
}

std::uint64_t ros1_time(std::int64_t ns) {
  const auto sec = static_cast<std::uint64_t>(ns / 1000000000LL);
  const auto nsec = static_cast<std::uint64_t>(ns % 1000000000LL);
  return sec | (nsec << 32);
}

// The message definitions (ROS 1 connection headers carry them so tools can decode without the
// package). Written from the .msg files of each package.
const char* kHeaderDef = "MSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n";
const char* kVector3Def = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n";
const char* kQuatDef =
    "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n";
const char* kSep =
    "================================================================================\n";

std::string definition(const std::string& type) {
  const std::string t = ros_type_name(type);
  if (t.find("/ProjectedSonarImage") != std::string::npos) {
    const std::string pkg = t.substr(0, t.find('/'));
    return "std_msgs/Header header\nPingInfo ping_info\ngeometry_msgs/Vector3[] beam_directions\n"
           "float32[] ranges\nSonarImageData image\n" +
           std::string(kSep) + kHeaderDef + kSep + "MSG: " + pkg +
           "/PingInfo\nfloat32 frequency\nfloat32 sound_speed\nfloat32[] tx_beamwidths\n"
           "float32[] rx_beamwidths\n" +
           kSep + kVector3Def + kSep + "MSG: " + pkg +
           "/SonarImageData\nbool is_bigendian\nuint32 DTYPE_UINT8=0\nuint32 DTYPE_INT8=1\n"
           "uint32 DTYPE_UINT16=2\nuint32 DTYPE_INT16=3\nuint32 DTYPE_UINT32=4\n"
           "uint32 DTYPE_INT32=5\nuint32 DTYPE_UINT64=6\nuint32 DTYPE_INT64=7\n"
           "uint32 DTYPE_FLOAT32=8\nuint32 DTYPE_FLOAT64=9\nuint32 dtype\nuint32 beam_count\n"
           "uint8[] data\n";
  }
  if (t == "nav_msgs/Odometry") {
    return "Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n"
           "geometry_msgs/TwistWithCovariance twist\n" +
           std::string(kSep) + kHeaderDef + kSep +
           "MSG: geometry_msgs/PoseWithCovariance\nPose pose\nfloat64[36] covariance\n" + kSep +
           "MSG: geometry_msgs/Pose\nPoint position\nQuaternion orientation\n" + kSep +
           "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n" + kSep + kQuatDef + kSep +
           "MSG: geometry_msgs/TwistWithCovariance\nTwist twist\nfloat64[36] covariance\n" + kSep +
           "MSG: geometry_msgs/Twist\nVector3 linear\nVector3 angular\n" + kSep + kVector3Def;
  }
  if (t == "tf2_msgs/TFMessage") {
    return "geometry_msgs/TransformStamped[] transforms\n" + std::string(kSep) +
           "MSG: geometry_msgs/TransformStamped\nHeader header\nstring child_frame_id\n"
           "Transform transform\n" +
           kSep + kHeaderDef + kSep +
           "MSG: geometry_msgs/Transform\nVector3 translation\nQuaternion rotation\n" + kSep +
           kVector3Def + kSep + kQuatDef;
  }
  return "";
}

// MD5 sums of the types we write (ROS 1's genmsg values, as the packages' generated code states
// them; a sum covers the definition, not the package name, so both ProjectedSonarImage packages
// share one); "*" (any) for the rest.
std::string md5(const std::string& type) {
  const std::string t = ros_type_name(type);
  if (t.find("/ProjectedSonarImage") != std::string::npos)
    return "c72fc8e29ab227a547720a36666022fd";
  if (t == "nav_msgs/Odometry") return "cd5e73d190d741a2f92e81eda573aca7";
  if (t == "tf2_msgs/TFMessage") return "94810edda583a504dfda3829e70d7eec";
  if (t == "geometry_msgs/PoseStamped") return "d3812c3cbc69362b77dc0b19b345f8f5";
  if (t == "sensor_msgs/Image") return "060021388200f6f0f447d0fcd9c64743";
  return "*";
}

// A chunk's records compressed as rosbag does (bz2 block size 9; lz4 frames as roslz4 writes them).
std::vector<std::uint8_t> compress(const std::string& how, const std::vector<std::uint8_t>& in,
                                   const fs::path& file) {
  if (how == "none") return in;
  std::vector<std::uint8_t> out;
  if (how == "bz2") {
    unsigned int n = static_cast<unsigned int>(in.size() + in.size() / 100 + 600);
    out.resize(n);
    const int rc =
        BZ2_bzBuffToBuffCompress(reinterpret_cast<char*>(out.data()), &n,
                                 const_cast<char*>(reinterpret_cast<const char*>(in.data())),
                                 static_cast<unsigned int>(in.size()), 9, 0, 0);
    if (rc != BZ_OK)
      throw Error(file.string() + ": bzip2 compression failed (" + std::to_string(rc) + ")");
    out.resize(n);
    return out;
  }
  // ROS 1 reads lz4 chunks with its own roslz4 stream decoder, which takes a subset of the LZ4
  // frame format only: independent blocks, no block checksums, no content size, a content
  // checksum, blocks of 64 KB to 4 MB. liblz4's defaults (linked blocks, no content checksum) are
  // refused by it ("malformed data to decompress"); these are what `rosbag record --lz4` writes.
  LZ4F_preferences_t prefs{};
  prefs.frameInfo.blockSizeID = LZ4F_max1MB;
  prefs.frameInfo.blockMode = LZ4F_blockIndependent;
  prefs.frameInfo.contentChecksumFlag = LZ4F_contentChecksumEnabled;
  prefs.frameInfo.blockChecksumFlag = LZ4F_noBlockChecksum;
  prefs.frameInfo.contentSize = 0;
  out.resize(LZ4F_compressFrameBound(in.size(), &prefs));
  const std::size_t n = LZ4F_compressFrame(out.data(), out.size(), in.data(), in.size(), &prefs);
  if (LZ4F_isError(n)) {
    throw Error(file.string() + ": lz4 compression failed (" + LZ4F_getErrorName(n) + ")");
  }
  out.resize(n);
  return out;
}

}  // namespace

std::unique_ptr<BagReader> open_ros1(const fs::path& bag) { return std::make_unique<Ros1Bag>(bag); }

void write_ros1(const fs::path& file, const std::vector<OutTopic>& topics, const NextMessage& next,
                const std::string& compression) {
  if (compression != "none" && compression != "bz2" && compression != "lz4") {
    throw Error("ROS 1 chunk compression '" + compression + "' (none, bz2 or lz4)");
  }
  std::ofstream f(file, std::ios::binary | std::ios::trunc);
  if (!f) throw Error(file.string() + ": cannot create the bag");
  std::uint64_t written = 0;
  auto emit = [&](const std::vector<std::uint8_t>& b) {
    f.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    written += b.size();
  };
  emit(std::vector<std::uint8_t>(kMagic, kMagic + kMagicLen));
  // Bag header: rewritten at the end; padded to 4096 bytes as rosbag does.
  auto bag_header = [&](std::uint64_t index_pos, std::uint32_t conns, std::uint32_t chunks) {
    std::vector<std::uint8_t> h;
    put_field_t<std::uint8_t>(h, "op", kBagHeader);
    put_field_t<std::uint64_t>(h, "index_pos", index_pos);
    put_field_t<std::uint32_t>(h, "conn_count", conns);
    put_field_t<std::uint32_t>(h, "chunk_count", chunks);
    std::vector<std::uint8_t> rec;
    const std::vector<std::uint8_t> pad(4096 - 8 - h.size(), ' ');
    put_record(rec, h, pad.data(), pad.size());
    return rec;
  };
  emit(bag_header(0, 0, 0));
  auto connection_record = [&](std::uint32_t id, std::vector<std::uint8_t>& dst) {
    const OutTopic& t = topics[id];
    const std::string type = ros_type_name(t.type);
    std::vector<std::uint8_t> h, d;
    put_field_t<std::uint8_t>(h, "op", kConnection);
    put_field_t<std::uint32_t>(h, "conn", id);
    put_field(h, "topic", t.name);
    put_field(d, "topic", t.name);
    put_field(d, "type", type);
    put_field(d, "md5sum", md5(type));
    put_field(d, "message_definition", definition(type));
    put_field(d, "callerid", std::string("/sonar3d_export"));
    if (t.latched) put_field(d, "latching", std::string("1"));
    put_record(dst, h, d.data(), d.size());
  };

  struct ChunkInfo {
    std::uint64_t pos;
    std::int64_t start, end;
    std::map<std::uint32_t, std::uint32_t> counts;
  };
  std::vector<ChunkInfo> infos;
  std::vector<bool> declared(topics.size(), false);
  OutMessage m;
  bool more = next(m);
  while (more) {
    // One chunk of up to ~768 KB of records, uncompressed.
    std::vector<std::uint8_t> chunk;
    ChunkInfo info{written, m.time_ns, m.time_ns, {}};
    std::map<std::uint32_t, std::vector<std::pair<std::uint64_t, std::uint32_t>>> index;
    while (more && (chunk.empty() || chunk.size() < (768u << 10))) {
      if (m.topic < 0 || static_cast<std::size_t>(m.topic) >= topics.size()) {
        throw Error(file.string() + ": a message names topic " + std::to_string(m.topic));
      }
      const auto id = static_cast<std::uint32_t>(m.topic);
      if (!declared[id]) {
        connection_record(id, chunk);
        declared[id] = true;
      }
      std::vector<std::uint8_t> h;
      put_field_t<std::uint8_t>(h, "op", kMsgData);
      put_field_t<std::uint32_t>(h, "conn", id);
      put_field_t<std::uint64_t>(h, "time", ros1_time(m.time_ns));
      index[id].emplace_back(ros1_time(m.time_ns), static_cast<std::uint32_t>(chunk.size()));
      put_record(chunk, h, m.data.data(), m.data.size());
      info.start = std::min(info.start, m.time_ns);
      info.end = std::max(info.end, m.time_ns);
      ++info.counts[id];
      more = next(m);
    }
    std::vector<std::uint8_t> h, rec;
    put_field_t<std::uint8_t>(h, "op", kChunk);
    put_field(h, "compression", compression);
    put_field_t<std::uint32_t>(h, "size", static_cast<std::uint32_t>(chunk.size()));
    const std::vector<std::uint8_t> packed = compress(compression, chunk, file);
    put_record(rec, h, packed.data(), packed.size());
    emit(rec);
    for (const auto& [id, entries] : index) {
      std::vector<std::uint8_t> ih, d, irec;
      put_field_t<std::uint8_t>(ih, "op", kIndexData);
      put_field_t<std::uint32_t>(ih, "ver", 1);
      put_field_t<std::uint32_t>(ih, "conn", id);
      put_field_t<std::uint32_t>(ih, "count", static_cast<std::uint32_t>(entries.size()));
      for (const auto& [t, off] : entries) {
        bin::append<std::uint64_t>(d, t);
        bin::append<std::uint32_t>(d, off);
      }
      put_record(irec, ih, d.data(), d.size());
      emit(irec);
    }
    infos.push_back(info);
  }
  const std::uint64_t index_pos = written;
  std::uint32_t conns = 0;
  std::vector<std::uint8_t> tail;
  for (std::uint32_t id = 0; id < topics.size(); ++id) {
    if (!declared[id]) continue;
    connection_record(id, tail);
    ++conns;
  }
  for (const ChunkInfo& c : infos) {
    std::vector<std::uint8_t> h, d;
    put_field_t<std::uint8_t>(h, "op", kChunkInfo);
    put_field_t<std::uint32_t>(h, "ver", 1);
    put_field_t<std::uint64_t>(h, "chunk_pos", c.pos);
    put_field_t<std::uint64_t>(h, "start_time", ros1_time(c.start));
    put_field_t<std::uint64_t>(h, "end_time", ros1_time(c.end));
    put_field_t<std::uint32_t>(h, "count", static_cast<std::uint32_t>(c.counts.size()));
    for (const auto& [id, n] : c.counts) {
      bin::append<std::uint32_t>(d, id);
      bin::append<std::uint32_t>(d, n);
    }
    put_record(tail, h, d.data(), d.size());
  }
  emit(tail);
  const auto rec = bag_header(index_pos, conns, static_cast<std::uint32_t>(infos.size()));
  f.seekp(static_cast<std::streamoff>(kMagicLen));
  f.write(reinterpret_cast<const char*>(rec.data()), static_cast<std::streamsize>(rec.size()));
  f.flush();
  if (!f) throw Error(file.string() + ": write failed");
}

}  // namespace sonar3d::bag
