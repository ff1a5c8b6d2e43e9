// rosbag2's sqlite3 storage (rosbag2_storage_default_plugins): tables topics(id, name, type, serialization_format,
// offered_qos_profiles[, type_description_hash]), messages(id, topic_id, timestamp, data) and, from Iron on,
// message_definitions(topic_type, encoding, encoded_message_definition, type_description_hash).
#include "formats/ros2_bag.h"

#include <sqlite3.h>
#include <yaml-cpp/yaml.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <sstream>

#include "formats/compression.h"

namespace driftlab::formats {

struct SqliteBagReader::Db {
  sqlite3* db = nullptr;
  std::vector<uint8_t> image;  // from_memory: sqlite reads the image in place
  // The work sqlite may do for this file, in progress-handler calls (one per kOpsPerCall virtual machine
  // operations): a schema is code (a generated column, a view's expression), so a hostile file could ask for
  // unbounded work. Reading rosbag2's tables costs a few hundred operations per row and a row takes at least a few
  // bytes, so 64 operations per byte of file plus a floor is far above what any real bag needs.
  static constexpr int kOpsPerCall = 1000;
  uint64_t calls_left = 0;
  bool exhausted = false;
  void budget(uint64_t file_bytes) {
    calls_left = (64 * file_bytes + 20'000'000) / kOpsPerCall;
    sqlite3_progress_handler(db, kOpsPerCall, &Db::on_progress, this);
    // Views and triggers in the file may not call functions with side effects.
    sqlite3_db_config(db, SQLITE_DBCONFIG_TRUSTED_SCHEMA, 0, nullptr);
  }
  static int on_progress(void* self) {
    auto* d = static_cast<Db*>(self);
    if (d->calls_left == 0) return d->exhausted = true;
    --d->calls_left;
    return 0;
  }
  std::string error() const {
    return exhausted ? std::string("reading asks for far more work than the file's size allows (a damaged or hostile "
                                   "schema); stopped")
                     : std::string(sqlite3_errmsg(db));
  }
  ~Db() {
    if (db) sqlite3_close(db);
  }
};

SqliteBagReader::SqliteBagReader() : db_(std::make_unique<Db>()) {}
SqliteBagReader::SqliteBagReader(SqliteBagReader&&) noexcept = default;
SqliteBagReader& SqliteBagReader::operator=(SqliteBagReader&&) noexcept = default;
SqliteBagReader::~SqliteBagReader() = default;

bool SqliteBagReader::looks_like(std::span<const uint8_t> head) {
  return head.size() >= 16 && std::memcmp(head.data(), "SQLite format 3\0", 16) == 0;
}

bool looks_like_zstd(std::span<const uint8_t> head) {
  return head.size() >= 4 && head[0] == 0x28 && head[1] == 0xB5 && head[2] == 0x2F && head[3] == 0xFD;
}

namespace {

/// A prepared statement, finalized on scope exit.
class Stmt {
 public:
  Stmt(sqlite3* db, const char* sql) { rc_ = sqlite3_prepare_v2(db, sql, -1, &s_, nullptr); }
  ~Stmt() { sqlite3_finalize(s_); }
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;
  bool ok() const { return rc_ == SQLITE_OK && s_ != nullptr; }
  sqlite3_stmt* get() { return s_; }
  std::string text(int col) {
    const auto* p = sqlite3_column_text(s_, col);
    return p ? std::string(reinterpret_cast<const char*>(p), static_cast<size_t>(sqlite3_column_bytes(s_, col)))
             : std::string();
  }

 private:
  sqlite3_stmt* s_ = nullptr;
  int rc_ = SQLITE_ERROR;
};

bool has_table(sqlite3* db, const char* name) {
  Stmt s(db, "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?");
  if (!s.ok()) return false;
  sqlite3_bind_text(s.get(), 1, name, -1, SQLITE_STATIC);
  return sqlite3_step(s.get()) == SQLITE_ROW;
}

uint64_t fs_size(const std::string& path) {
  std::error_code ec;
  const auto n = std::filesystem::file_size(path, ec);
  return ec ? 0 : n;
}

/// The file padded with zeros to the size its header gives, when it is shorter (a cut file) and small enough to
/// hold in memory; empty otherwise.
std::vector<uint8_t> padded_image(const std::string& path) {
  constexpr uint64_t kMaxBytes = uint64_t{2} << 30;
  const uint64_t size = fs_size(path);
  if (size < 100 || size > kMaxBytes) return {};
  std::vector<uint8_t> b(size);
  FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return {};
  const size_t got = std::fread(b.data(), 1, b.size(), f);
  std::fclose(f);
  if (got != size || !SqliteBagReader::looks_like(b)) return {};
  uint32_t page = (uint32_t{b[16]} << 8) | b[17];
  if (page == 1) page = 65536;
  const uint64_t pages = (uint64_t{b[28]} << 24) | (uint64_t{b[29]} << 16) | (uint64_t{b[30]} << 8) | b[31];
  const uint64_t want = pages * page;
  if (want <= size || want > kMaxBytes) return {};
  b.resize(want, 0);
  return b;
}

}  // namespace

Status SqliteBagReader::load_tables() {
  sqlite3* db = db_->db;
  if (!has_table(db, "topics") || !has_table(db, "messages")) {
    const std::string why = sqlite3_errcode(db) != SQLITE_OK && sqlite3_errcode(db) != SQLITE_ROW &&
                              sqlite3_errcode(db) != SQLITE_DONE
                          ? db_->error()
                          : std::string("an SQLite database without rosbag2's topics and messages tables");
    return Error(name_ + ": not a ROS 2 bag: " + why);
  }
  {
    Stmt s(db, "SELECT id, name, type, serialization_format, offered_qos_profiles FROM topics ORDER BY id");
    if (!s.ok()) return Error(name_ + ": topics table: " + db_->error());
    int rc;
    while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
      Ros2TopicInfo t;
      const int64_t id = sqlite3_column_int64(s.get(), 0);
      t.name = s.text(1);
      t.type = s.text(2);
      t.serialization_format = s.text(3);
      t.offered_qos_profiles = s.text(4);
      topics_.emplace(id, std::move(t));
    }
    if (rc != SQLITE_DONE) return Error(name_ + ": topics table: " + db_->error());
  }
  if (has_table(db, "message_definitions")) {
    Stmt s(db, "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions");
    if (s.ok()) {
      while (sqlite3_step(s.get()) == SQLITE_ROW) definitions_[s.text(0)] = {s.text(1), s.text(2)};
    }
  }
  return {};
}

Result<SqliteBagReader> SqliteBagReader::open(const std::string& path) {
  SqliteBagReader r;
  r.name_ = path;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return Error(path + ": not a file");
  // With a write-ahead log or a rollback journal beside it (a recorder writing, or killed), read-only first: it
  // sees the log's transactions; then, in a read-only folder whose journal cannot be opened, as immutable (no locks,
  // no journal). With neither, as immutable at once: a read-only connection to a bag in WAL mode leaves an empty
  // -wal and a -shm file beside it, in the user's folder, which a reader must not write into.
  const bool journal = std::filesystem::exists(path + "-wal", ec) || std::filesystem::exists(path + "-journal", ec);
  for (const bool immutable : {false, true}) {
    if (!immutable && !journal) continue;
    if (r.db_->db) sqlite3_close(r.db_->db);
    r.db_->db = nullptr;
    int rc;
    if (immutable) {
      std::string uri = "file:";
      for (const char c : std::filesystem::absolute(path).string()) {
        if (c == '?' || c == '#' || c == '%') {
          char buf[4];
          std::snprintf(buf, sizeof(buf), "%%%02X", static_cast<unsigned char>(c));
          uri += buf;
        } else {
          uri += c;
        }
      }
      rc = sqlite3_open_v2((uri + "?immutable=1").c_str(), &r.db_->db, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, nullptr);
    } else {
      rc = sqlite3_open_v2(path.c_str(), &r.db_->db, SQLITE_OPEN_READONLY, nullptr);
    }
    if (rc != SQLITE_OK) {
      if (immutable) return Error(path + ": " + (r.db_->db ? sqlite3_errmsg(r.db_->db) : "cannot open"));
      continue;
    }
    r.db_->budget(fs_size(path));
    if (Status s = r.load_tables(); !s) {
      if (!immutable) continue;
      // A file cut short (a recorder killed, a copy interrupted): sqlite reads the pages it has when the missing
      // ones read as zeros, so the rows before the cut can be read.
      if (auto padded = padded_image(path); !padded.empty()) {
        auto m = from_memory(padded);
        if (m) {
          m->name_ = path;
          m->note_ = "the file is cut short (" + std::to_string(fs_size(path)) + " of the " +
                     std::to_string(padded.size()) + " bytes its header gives); reading what is intact";
          return m;
        }
      }
      return s.error();
    }
    return r;
  }
  return Error(path + ": cannot open");
}

Result<SqliteBagReader> SqliteBagReader::from_memory(std::span<const uint8_t> bytes) {
  SqliteBagReader r;
  r.name_ = "db3";
  if (!looks_like(bytes)) return Error("db3: not an SQLite database");
  if (sqlite3_open_v2(":memory:", &r.db_->db, SQLITE_OPEN_READWRITE, nullptr) != SQLITE_OK) {
    return Error("db3: cannot open an in-memory database");
  }
  r.db_->image.assign(bytes.begin(), bytes.end());
  if (sqlite3_deserialize(r.db_->db, "main", r.db_->image.data(), static_cast<sqlite3_int64>(r.db_->image.size()),
                          static_cast<sqlite3_int64>(r.db_->image.size()), SQLITE_DESERIALIZE_READONLY) != SQLITE_OK) {
    return Error(std::string("db3: ") + sqlite3_errmsg(r.db_->db));
  }
  r.db_->budget(bytes.size());
  if (Status s = r.load_tables(); !s) return s.error();
  return r;
}

int64_t SqliteBagReader::read(const std::function<void(const Ros2DbMessage&)>& on_message,
                              const std::function<void(const Ros2DbProblem&)>& on_problem) {
  sqlite3* db = db_->db;
  int64_t delivered = 0;
  if (!note_.empty()) on_problem({0, note_});
  // Walked by id (the order rosbag2 inserted them, as they arrived), so that after a damaged page reading can
  // go on from the next id that can be reached.
  Stmt s(db, "SELECT id, topic_id, timestamp, data FROM messages WHERE id > ? ORDER BY id");
  if (!s.ok()) {
    on_problem({0, "messages table: " + db_->error()});
    return 0;
  }
  int64_t last = INT64_MIN;
  std::map<int64_t, bool> unknown_reported;
  // After damage: where it was met (the last id read), and why; reported once reading goes on or gives up.
  int64_t damaged_after = INT64_MIN;
  std::string damage;
  int attempt = 0;
  for (;;) {
    sqlite3_reset(s.get());
    sqlite3_bind_int64(s.get(), 1, last);
    int rc;
    while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
      const int64_t id = sqlite3_column_int64(s.get(), 0);
      if (last != INT64_MIN && id <= last) {
        // rosbag2's ids are integer keys; ids that repeat or are not integers (read as the integer below them)
        // would have reading go round the same rows for ever.
        on_problem({last, "message ids after " + std::to_string(last) +
                              " repeat or are not integers (not rosbag2's messages table); reading stopped there"});
        return delivered;
      }
      if (!damage.empty()) {
        on_problem({damaged_after, "rows after id " + std::to_string(damaged_after) + " cannot be read (" + damage +
                                       "); reading went on at id " + std::to_string(id)});
        damage.clear();
        attempt = 0;
      }
      last = id;
      const int64_t topic = sqlite3_column_int64(s.get(), 1);
      auto t = topics_.find(topic);
      if (t == topics_.end()) {
        if (!unknown_reported[topic]) {
          on_problem({id, "a message on topic id " + std::to_string(topic) + ", which the topics table does not hold"});
        }
        unknown_reported[topic] = true;
        continue;
      }
      const auto* data = static_cast<const uint8_t*>(sqlite3_column_blob(s.get(), 3));
      const auto size = static_cast<size_t>(sqlite3_column_bytes(s.get(), 3));
      on_message({&t->second, sqlite3_column_int64(s.get(), 2), {data, size}, id});
      ++delivered;
    }
    if (rc == SQLITE_DONE && damage.empty()) break;
    if (rc != SQLITE_DONE && damage.empty()) {
      damage = db_->error();
      damaged_after = last == INT64_MIN ? 0 : last;
    }
    if (db_->exhausted) {
      on_problem({damaged_after, "rows after id " + std::to_string(damaged_after) + ": " + damage});
      break;
    }
    // Try the ids after the damage, further each time (rows are numbered from 1 as they were inserted).
    if (rc == SQLITE_DONE || attempt >= 40 || damaged_after > INT64_MAX - (int64_t{1} << attempt)) {
      on_problem({damaged_after, "rows after id " + std::to_string(damaged_after) + " cannot be read (" + damage +
                                     "); nothing readable after them"});
      break;
    }
    last = damaged_after + (int64_t{1} << attempt++);
  }
  return delivered;
}

// --- metadata.yaml ------------------------------------------------------------------------------------------

namespace {

template <typename T>
T scalar(const YAML::Node& n, const T& fallback) {
  if (!n || !n.IsScalar()) return fallback;
  try {
    return n.as<T>();
  } catch (const YAML::Exception&) {
    return fallback;
  }
}

/// metadata.yaml's keys, read without a YAML exception ever escaping: subscripting a missing key, a scalar or a
/// list throws in yaml-cpp, so every step is checked and a missing or mistyped key is an error naming the file,
/// the line and the dotted key.
class MetadataReader {
 public:
  explicit MetadataReader(std::string path) : path_(std::move(path)) {}

  /// The child `key` of map `n` (named `where`), or an invalid node and an error when it is missing.
  YAML::Node child(const YAML::Node& n, const std::string& where, const std::string& key, bool required) {
    if (!n || !n.IsMap()) {
      if (required) fail(n, where, "not a map");
      return YAML::Node(YAML::NodeType::Undefined);
    }
    YAML::Node c;
    try {
      c = n[key];
    } catch (const YAML::Exception&) {
      c = YAML::Node(YAML::NodeType::Undefined);
    }
    if ((!c || c.IsNull()) && required) fail(n, join(where, key), "missing");
    return c;
  }

  template <typename T>
  T value(const YAML::Node& n, const std::string& where, const std::string& key, bool required, const T& fallback,
          const char* what) {
    const YAML::Node c = child(n, where, key, required);
    if (!c || c.IsNull()) return fallback;
    if (!c.IsScalar()) {
      fail(c, join(where, key), std::string("not ") + what);
      return fallback;
    }
    try {
      return c.as<T>();
    } catch (const YAML::Exception&) {
      fail(c, join(where, key), std::string("not ") + what);
      return fallback;
    }
  }

  Status status() const { return error_.empty() ? Status{} : Status{Error(error_)}; }

 private:
  static std::string join(const std::string& where, const std::string& key) {
    return where.empty() ? key : where + "." + key;
  }
  void fail(const YAML::Node& at, const std::string& key, const std::string& why) {
    if (!error_.empty()) return;  // the first one
    std::string line;
    if (at.IsDefined() && at.Mark().line >= 0) line = ":" + std::to_string(at.Mark().line + 1);
    error_ = path_ + line + ": " + key + ": " + why;
  }

  std::string path_;
  std::string error_;
};

}  // namespace

Result<Ros2BagMetadata> read_ros2_metadata(const std::string& folder) {
  const std::string path = folder + "/metadata.yaml";
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    return Error(path + ": cannot be read");
  } catch (const YAML::Exception& e) {
    return Error(path + ": line " + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  MetadataReader r(path);
  const std::string top = "rosbag2_bagfile_information";
  const YAML::Node info = r.child(root, "", top, false);
  if (!info || !info.IsMap()) return Error(path + ": no rosbag2_bagfile_information map");
  Ros2BagMetadata m;
  // The keys every rosbag2 version writes and the import reads are required; the ones later versions added (or
  // that only describe) default when absent, but are refused when present with the wrong type.
  m.version = r.value<int>(info, top, "version", false, 0, "an integer");
  m.storage_identifier = r.value<std::string>(info, top, "storage_identifier", false, "", "a string");
  m.compression_format = r.value<std::string>(info, top, "compression_format", false, "", "a string");
  m.compression_mode = r.value<std::string>(info, top, "compression_mode", false, "", "a string");
  m.message_count = r.value<int64_t>(info, top, "message_count", true, 0, "an integer");
  m.starting_time_ns = r.value<int64_t>(r.child(info, top, "starting_time", true), top + ".starting_time",
                                        "nanoseconds_since_epoch", true, 0, "an integer");
  m.duration_ns =
      r.value<int64_t>(r.child(info, top, "duration", true), top + ".duration", "nanoseconds", true, 0, "an integer");
  if (const auto files = r.child(info, top, "relative_file_paths", true); files && files.IsSequence()) {
    for (const auto& f : files) {
      const auto p = scalar<std::string>(f, "");
      if (p.empty()) return Error(path + ": relative_file_paths: an entry that is not a file name");
      m.relative_file_paths.push_back(p);
    }
  } else if (Status s = r.status(); !s) {
    return s.error();
  } else {
    return Error(path + ": " + top + ".relative_file_paths: not a list");
  }
  const std::string twmc = top + ".topics_with_message_count";
  if (const auto topics = r.child(info, top, "topics_with_message_count", true); topics && topics.IsSequence()) {
    size_t i = 0;
    for (const auto& t : topics) {
      const std::string where = twmc + "[" + std::to_string(i++) + "]";
      const auto md = r.child(t, where, "topic_metadata", true);
      const std::string mdw = where + ".topic_metadata";
      Ros2TopicInfo ti;
      ti.name = r.value<std::string>(md, mdw, "name", true, "", "a string");
      ti.type = r.value<std::string>(md, mdw, "type", true, "", "a string");
      ti.serialization_format = r.value<std::string>(md, mdw, "serialization_format", false, "", "a string");
      // A string up to Iron, a list of maps from Jazzy on: only a string is kept.
      ti.offered_qos_profiles = scalar<std::string>(r.child(md, mdw, "offered_qos_profiles", false), "");
      ti.type_description_hash = r.value<std::string>(md, mdw, "type_description_hash", false, "", "a string");
      ti.message_count = r.value<int64_t>(t, where, "message_count", true, 0, "an integer");
      if (!r.status()) break;
      m.topics.push_back(std::move(ti));
    }
  } else if (topics && r.status()) {
    return Error(path + ": " + twmc + ": not a list");
  }
  if (Status s = r.status(); !s) return s.error();
  return m;
}

namespace {
/// A YAML double-quoted scalar.
std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (c == '\n') {
      out += "\\n";
    } else {
      out += c;
    }
  }
  return out + "\"";
}
}  // namespace

std::string ros2_metadata_yaml(const std::string& storage_identifier, const std::vector<Ros2TopicInfo>& topics,
                               const std::vector<Ros2FileInfo>& files) {
  int64_t start = INT64_MAX, end = INT64_MIN, count = 0;
  for (const auto& f : files) {
    if (f.message_count == 0) continue;
    start = std::min(start, f.starting_time_ns);
    end = std::max(end, f.starting_time_ns + f.duration_ns);
    count += f.message_count;
  }
  if (count == 0) start = end = 0;
  std::ostringstream o;
  o << "rosbag2_bagfile_information:\n"
    << "  version: 8\n"
    << "  storage_identifier: " << storage_identifier << "\n"
    << "  duration:\n    nanoseconds: " << end - start << "\n"
    << "  starting_time:\n    nanoseconds_since_epoch: " << start << "\n"
    << "  message_count: " << count << "\n"
    << "  topics_with_message_count:\n";
  if (topics.empty()) o << "    []\n";
  for (const auto& t : topics) {
    o << "    - topic_metadata:\n"
      << "        name: " << quoted(t.name) << "\n"
      << "        type: " << t.type << "\n"
      << "        serialization_format: " << t.serialization_format << "\n"
      << "        offered_qos_profiles: " << quoted(t.offered_qos_profiles) << "\n"
      << "        type_description_hash: " << quoted(t.type_description_hash) << "\n"
      << "      message_count: " << t.message_count << "\n";
  }
  o << "  compression_format: \"\"\n"
    << "  compression_mode: \"\"\n"
    << "  relative_file_paths:\n";
  for (const auto& f : files) o << "    - " << quoted(f.path) << "\n";
  o << "  files:\n";
  for (const auto& f : files) {
    o << "    - path: " << quoted(f.path) << "\n"
      << "      starting_time:\n        nanoseconds_since_epoch: " << f.starting_time_ns << "\n"
      << "      duration:\n        nanoseconds: " << f.duration_ns << "\n"
      << "      message_count: " << f.message_count << "\n";
  }
  o << "  custom_data: ~\n"
    << "  ros_distro: \"\"\n";
  return o.str();
}

Status decompress_zstd_file(const std::string& in, const std::string& out) {
  return decompress_file(Codec::kZstd, in, out);
}

}  // namespace driftlab::formats
