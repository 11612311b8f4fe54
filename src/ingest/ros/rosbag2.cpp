// ROS 2 bags: the storage (MCAP through mcap.h, SQLite .db3 through libsqlite3) gives CDR
// messages; cdr.h decodes them and bag_dataset.h makes the frames, as for ROS 1 bags.

#include "rosbag2.h"

#include <sqlite3.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <sstream>

#include "bag_dataset.h"
#include "cdr.h"
#include "chronomap/core/error.h"
#include "chronomap/core/pose.h"
#include "mcap.h"
#include "rosbag1.h"

namespace chronomap {

namespace fs = std::filesystem;

namespace {

constexpr char kSqliteMagic[16] = {'S', 'Q', 'L', 'i', 't', 'e', ' ', 'f', 'o', 'r', 'm', 'a', 't', ' ', '3', '\0'};
constexpr uint8_t kMcapMagic[5] = {0x89, 'M', 'C', 'A', 'P'};

enum class Storage { Mcap, Sqlite };

/// The first bytes of a file (fewer when it is shorter).
std::string firstBytes(const fs::path& path, size_t n) {
  std::ifstream in(path, std::ios::binary);
  std::string out(n, '\0');
  in.read(out.data(), static_cast<std::streamsize>(n));
  out.resize(static_cast<size_t>(std::max<std::streamsize>(in.gcount(), 0)));
  return out;
}

std::optional<Storage> storageOfFile(const fs::path& path) {
  const std::string head = firstBytes(path, 16);
  if (head.size() >= 5 && std::memcmp(head.data(), kMcapMagic, 5) == 0) return Storage::Mcap;
  if (head.size() == 16 && std::memcmp(head.data(), kSqliteMagic, 16) == 0) return Storage::Sqlite;
  if (path.extension() == ".mcap") return Storage::Mcap;
  if (path.extension() == ".db3") return Storage::Sqlite;
  return std::nullopt;
}

std::string trim(std::string s) {
  const auto b = s.find_first_not_of(" \t\r\"'");
  const auto e = s.find_last_not_of(" \t\r\"'");
  return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

/// The storage files of a bag: the file itself, or those metadata.yaml names in a folder (more
/// than one when rosbag2 split the recording), in the order it lists them.
std::vector<fs::path> storageFiles(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw UsageError(path.string() + ": no such file or folder");
  if (!fs::is_directory(path, ec)) return {path};
  const fs::path meta = path / "metadata.yaml";
  std::ifstream in(meta);
  if (!in) throw UsageError(path.string() + ": a ROS 2 bag folder holds metadata.yaml; this one does not");
  // rosbag2's metadata: the file names are the items under relative_file_paths.
  std::vector<std::string> files;
  std::string line;
  bool in_list = false;
  size_t list_indent = 0;
  while (std::getline(in, line)) {
    const size_t indent = line.find_first_not_of(' ');
    if (indent == std::string::npos) continue;
    const std::string body = line.substr(indent);
    if (body.rfind("relative_file_paths:", 0) == 0) {
      in_list = true;
      list_indent = indent;
      continue;
    }
    if (in_list) {
      if (body.rfind("- ", 0) == 0 && indent >= list_indent) {
        files.push_back(trim(body.substr(2)));
        continue;
      }
      in_list = false;
    }
  }
  if (files.empty()) {
    throw FormatError(meta.string() + ": no relative_file_paths (which storage file holds the messages?)");
  }
  std::vector<fs::path> out;
  for (const std::string& name : files) {
    const fs::path file = path / name;
    if (!fs::exists(file, ec)) throw DataError(meta.string() + ": names " + name + ", which is missing");
    out.push_back(file);
  }
  return out;
}

/// "sensor_msgs/msg/Image" -> "sensor_msgs/Image", the names bag_dataset.h knows.
std::string ros1Type(const std::string& type) {
  const auto at = type.find("/msg/");
  return at == std::string::npos ? type : type.substr(0, at) + type.substr(at + 4);
}

/// One message as the storage gives it during a pass.
struct Incoming {
  const std::string& topic;
  const std::string& type;      ///< ROS 2 name
  const std::string& encoding;  ///< serialisation: "cdr"
  uint64_t handle;
  std::span<const uint8_t> data;
};
using Visit = std::function<void(const Incoming&)>;

/// Where a ROS 2 bag's messages are stored.
class MessageStore {
 public:
  virtual ~MessageStore() = default;
  /// Every message of `wanted` (every topic when null), in the order of the storage.
  virtual void forEach(const std::set<std::string>* wanted, const Visit& fn) = 0;
  /// Topic name -> (ROS 2 type, count); the first message of each image topic is visited by `first`.
  virtual std::map<std::string, std::pair<std::string, uint64_t>> topics(const std::set<std::string>& types_first,
                                                                         const Visit& first) = 0;
  virtual mcap::MessageBytes message(uint64_t handle) const = 0;
  /// What the last pass could not read and why ("FILE: cut short ..."); empty when it read all.
  virtual std::string note() const { return {}; }
};

class McapStore : public MessageStore {
 public:
  explicit McapStore(const fs::path& path) : reader_(path), path_(path) {}

  std::string note() const override {
    const std::string note = reader_.truncationNote();
    return note.empty() ? note : path_.filename().string() + " " + note;
  }

  void forEach(const std::set<std::string>* wanted, const Visit& fn) override {
    refs_.clear();
    reader_.forEachMessage([&](const mcap::Message& m) {
      const mcap::Channel& ch = reader_.channels().at(m.channel);
      if (wanted && !wanted->count(ch.topic)) return;
      const uint64_t handle = refs_.size();
      refs_.push_back(m.ref);
      fn(Incoming{ch.topic, typeOf(ch), ch.message_encoding, handle, m.data});
    });
  }

  std::map<std::string, std::pair<std::string, uint64_t>> topics(const std::set<std::string>& types_first,
                                                                 const Visit& first) override {
    std::map<std::string, std::pair<std::string, uint64_t>> out;
    reader_.forEachMessage([&](const mcap::Message& m) {
      const mcap::Channel& ch = reader_.channels().at(m.channel);
      auto& entry = out[ch.topic];
      entry.first = typeOf(ch);
      if (entry.second++ == 0 && types_first.count(entry.first)) {
        first(Incoming{ch.topic, entry.first, ch.message_encoding, 0, m.data});
      }
    });
    // Channels without messages are topics too.
    for (const auto& [id, ch] : reader_.channels()) out.try_emplace(ch.topic, typeOf(ch), 0);
    return out;
  }

  mcap::MessageBytes message(uint64_t handle) const override { return reader_.message(refs_.at(handle)); }

 private:
  const std::string& typeOf(const mcap::Channel& ch) const {
    static const std::string none;
    auto it = reader_.schemas().find(ch.schema_id);
    return it == reader_.schemas().end() ? none : it->second.name;
  }
  mcap::Reader reader_;
  fs::path path_;
  std::vector<mcap::MessageRef> refs_;
};

/// rosbag2's SQLite storage: tables topics(id, name, type, serialization_format, ...) and
/// messages(id, topic_id, timestamp, data).
class SqliteStore : public MessageStore {
 public:
  explicit SqliteStore(const fs::path& path) : path_(path) {
    if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX, nullptr) != SQLITE_OK) {
      const std::string why = db_ ? sqlite3_errmsg(db_) : "no memory";
      sqlite3_close(db_);
      throw FormatError(path.string() + ": cannot open as SQLite (" + why + ")");
    }
    try {
      boundValues();
      const auto tables = column("SELECT name FROM sqlite_master WHERE type = 'table'");
      for (const char* table : {"topics", "messages"}) {
        if (std::find(tables.begin(), tables.end(), table) == tables.end()) {
          throw FormatError(path.string() + ": not a rosbag2 SQLite bag (no table '" + table + "')");
        }
        refuseComputedBytes(table);
      }
      Statement st(*this, "SELECT id, name, type, serialization_format FROM topics");
      while (st.step()) topics_[st.integer(0)] = {st.text(1), st.text(2), st.text(3)};
    } catch (...) {
      sqlite3_close(db_);
      throw;
    }
  }
  ~SqliteStore() override { sqlite3_close(db_); }

  void forEach(const std::set<std::string>* wanted, const Visit& fn) override {
    Statement st(*this, "SELECT id, topic_id, data FROM messages ORDER BY timestamp, id");
    while (st.step()) {
      const Topic& t = topic(st.integer(1));
      if (wanted && !wanted->count(t.name)) continue;
      fn(Incoming{t.name, t.type, t.format, static_cast<uint64_t>(st.integer(0)), st.blob(2)});
    }
  }

  std::map<std::string, std::pair<std::string, uint64_t>> topics(const std::set<std::string>& types_first,
                                                                 const Visit& first) override {
    std::map<std::string, std::pair<std::string, uint64_t>> out;
    for (const auto& [id, t] : topics_) out.try_emplace(t.name, t.type, 0);
    Statement counts(*this, "SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id");
    while (counts.step()) out[topic(counts.integer(0)).name].second += static_cast<uint64_t>(counts.integer(1));
    for (const auto& [id, t] : topics_) {
      if (!types_first.count(t.type)) continue;
      Statement st(*this, "SELECT id, data FROM messages WHERE topic_id = ? ORDER BY timestamp, id LIMIT 1");
      sqlite3_bind_int64(st.s, 1, id);
      if (st.step()) first(Incoming{t.name, t.type, t.format, static_cast<uint64_t>(st.integer(0)), st.blob(1)});
    }
    return out;
  }

  mcap::MessageBytes message(uint64_t handle) const override {
    std::lock_guard<std::mutex> lock(mutex_);
    Statement st(*this, "SELECT data FROM messages WHERE id = ?");
    sqlite3_bind_int64(st.s, 1, static_cast<sqlite3_int64>(handle));
    if (!st.step()) throw FormatError(path_.string() + ": message " + std::to_string(handle) + " is gone");
    const auto blob = st.blob(0);
    auto bytes = std::make_shared<std::vector<uint8_t>>(blob.begin(), blob.end());
    return {std::span<const uint8_t>(*bytes), bytes};
  }

 private:
  struct Topic {
    std::string name, type, format;
  };
  struct Statement {
    Statement(const SqliteStore& store, const char* sql) : store_(store) {
      if (sqlite3_prepare_v2(store.db_, sql, -1, &s, nullptr) != SQLITE_OK) store.fail();
    }
    ~Statement() { sqlite3_finalize(s); }
    Statement(const Statement&) = delete;
    Statement& operator=(const Statement&) = delete;
    bool step() {
      const int rc = sqlite3_step(s);
      if (rc == SQLITE_ROW) return true;
      if (rc != SQLITE_DONE) store_.fail();
      return false;
    }
    int64_t integer(int i) const { return sqlite3_column_int64(s, i); }
    std::string text(int i) const {
      const auto* p = sqlite3_column_text(s, i);
      return p ? std::string(reinterpret_cast<const char*>(p)) : std::string();
    }
    std::span<const uint8_t> blob(int i) const {
      const void* p = sqlite3_column_blob(s, i);
      const int n = sqlite3_column_bytes(s, i);
      return p ? std::span<const uint8_t>(static_cast<const uint8_t*>(p), static_cast<size_t>(n))
               : std::span<const uint8_t>();
    }
    sqlite3_stmt* s = nullptr;
    const SqliteStore& store_;
  };
  [[noreturn]] void fail() const { throw FormatError(path_.string() + ": SQLite: " + sqlite3_errmsg(db_)); }

  /// No value read may be longer than the bytes stored: the database file and its write-ahead
  /// log (at least 1 MiB, for SQLite's own small values). A stored value cannot exceed them;
  /// only a computed one could, and SQLite refuses to make it ("string or blob too big").
  void boundValues() {
    std::error_code ec;
    uintmax_t bytes = fs::file_size(path_, ec);
    if (ec) bytes = 0;
    const uintmax_t wal = fs::file_size(path_.string() + "-wal", ec);
    if (!ec) bytes += wal;
    const uintmax_t bound = std::clamp<uintmax_t>(bytes, uintmax_t{1} << 20, uintmax_t{INT32_MAX});
    sqlite3_limit(db_, SQLITE_LIMIT_LENGTH, static_cast<int>(bound));
  }

  /// A rosbag2 table holds stored bytes only: a virtual table or a generated column computes
  /// them when read (a 16 KiB file whose messages.data is zeroblob(900000000) would allocate
  /// 900 MB per message), so either is refused before anything is read.
  void refuseComputedBytes(const std::string& table) {
    Statement kind(*this, "SELECT sql FROM sqlite_master WHERE type = 'table' AND name = ?");
    sqlite3_bind_text(kind.s, 1, table.c_str(), -1, SQLITE_TRANSIENT);
    if (kind.step() && kind.text(0).rfind("CREATE VIRTUAL", 0) == 0) {
      throw FormatError(path_.string() + ": not a rosbag2 SQLite bag (table '" + table +
                        "' is a virtual table, which computes its rows instead of storing them)");
    }
    // table_xinfo's column 6 ("hidden") is 2 or 3 for a generated column.
    Statement columns(*this, ("PRAGMA table_xinfo(\"" + table + "\")").c_str());
    while (columns.step()) {
      if (columns.integer(6) >= 2) {
        throw FormatError(path_.string() + ": not a rosbag2 SQLite bag (column " + table + "." + columns.text(1) +
                          " is generated: computed when read, not stored bytes)");
      }
    }
  }
  std::vector<std::string> column(const char* sql) const {
    std::vector<std::string> out;
    Statement st(*this, sql);
    while (st.step()) out.push_back(st.text(0));
    return out;
  }
  const Topic& topic(int64_t id) const {
    auto it = topics_.find(id);
    if (it == topics_.end()) throw FormatError(path_.string() + ": a message of topic id " + std::to_string(id) + ", which the topics table lacks");
    return it->second;
  }

  fs::path path_;
  sqlite3* db_ = nullptr;
  std::map<int64_t, Topic> topics_;
  mutable std::mutex mutex_;
};

std::unique_ptr<MessageStore> openStore(const fs::path& file) {
  const auto storage = storageOfFile(file);
  if (!storage) throw FormatError(file.string() + ": neither MCAP nor SQLite (a ROS 2 bag's storage)");
  if (*storage == Storage::Mcap) return std::make_unique<McapStore>(file);
  return std::make_unique<SqliteStore>(file);
}

/// A bag split over several storage files (rosbag2 --max-bag-size or --max-bag-duration): their
/// messages one file after the other, as the metadata lists them; a handle is an index into the
/// messages this store has visited, each remembered as (file, that file's handle).
class SplitStore : public MessageStore {
 public:
  explicit SplitStore(const std::vector<fs::path>& files) {
    for (const fs::path& file : files) parts_.push_back(openStore(file));
  }

  std::string note() const override {
    std::string out;
    for (const auto& part : parts_) {
      const std::string note = part->note();
      if (!note.empty()) out += (out.empty() ? "" : "; ") + note;
    }
    return out;
  }

  void forEach(const std::set<std::string>* wanted, const Visit& fn) override {
    refs_.clear();
    for (size_t p = 0; p < parts_.size(); ++p) {
      parts_[p]->forEach(wanted, [&](const Incoming& m) {
        const uint64_t handle = refs_.size();
        refs_.emplace_back(p, m.handle);
        fn(Incoming{m.topic, m.type, m.encoding, handle, m.data});
      });
    }
  }

  std::map<std::string, std::pair<std::string, uint64_t>> topics(const std::set<std::string>& types_first,
                                                                 const Visit& first) override {
    std::map<std::string, std::pair<std::string, uint64_t>> out;
    std::set<std::string> seen;  // the first message of a topic is in the first file that has one
    for (const auto& part : parts_) {
      const auto topics = part->topics(types_first, [&](const Incoming& m) {
        if (seen.insert(m.topic).second) first(m);
      });
      for (const auto& [name, entry] : topics) {
        auto& merged = out[name];
        if (merged.first.empty()) merged.first = entry.first;
        merged.second += entry.second;
      }
    }
    return out;
  }

  mcap::MessageBytes message(uint64_t handle) const override {
    const auto& [part, inner] = refs_.at(handle);
    return parts_[part]->message(inner);
  }

 private:
  std::vector<std::unique_ptr<MessageStore>> parts_;
  std::vector<std::pair<size_t, uint64_t>> refs_;
};

std::unique_ptr<MessageStore> openStore(const std::vector<fs::path>& files) {
  if (files.size() == 1) return openStore(files.front());
  return std::make_unique<SplitStore>(files);
}

/// The name errors give a bag: its storage file, or the folder of a split bag.
fs::path bagName(const fs::path& given, const std::vector<fs::path>& files) {
  return files.size() == 1 ? files.front() : given;
}

/// "topic (encoding 'json')" refused: only CDR is decoded.
void requireCdr(const Incoming& m, const fs::path& file) {
  if (m.encoding != "cdr") {
    throw FormatError(file.string() + ": " + m.topic + " is encoded as '" + m.encoding +
                      "'; chronomap decodes ROS 2 messages in CDR only");
  }
}

/// The topics with their ROS 1 type names and, for images, the first message's encoding.
bag::TopicMap topicMap(MessageStore& store, const fs::path& file, std::map<std::string, std::string>* ros2_types) {
  bag::TopicMap out;
  const auto topics =
      store.topics({"sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage"}, [&](const Incoming& m) {
        if (m.encoding != "cdr") return;
        auto& info = out[m.topic];
        if (m.type == "sensor_msgs/msg/CompressedImage") {
          const auto im = cdr::compressedImage(m.data, file.string() + ": " + m.topic);
          info.encoding = std::string(im.view.format);
          info.frame_id = bag::frameName(im.header.frame_id);
        } else {
          const auto im = cdr::image(m.data, file.string() + ": " + m.topic);
          info.encoding = std::string(im.view.encoding);
          info.frame_id = bag::frameName(im.header.frame_id);
        }
      });
  for (const auto& [name, entry] : topics) {
    auto& info = out[name];
    info.type = ros1Type(entry.first);
    info.messages = entry.second;
    if (ros2_types) (*ros2_types)[name] = entry.first;
  }
  return out;
}

Eigen::Isometry3d transformOf(const cdr::Transform& t, const std::string& context) {
  return poseFromTranslationQuaternion({t.xyz[0], t.xyz[1], t.xyz[2]}, t.q[0], t.q[1], t.q[2], t.q[3], context);
}

class Ros2BagDataset : public bag::BagDataset {
 public:
  Ros2BagDataset(const fs::path& path, const DatasetSettings& s) : BagDataset(path, "ros2bag") {
    const std::vector<fs::path> files = storageFiles(path);
    file_ = bagName(path, files);
    path_ = file_;
    store_ = openStore(files);
    const bag::TopicMap topics = topicMap(*store_, file_, nullptr);
    const bag::Topics t = bag::chooseTopics(topics, s.bag, file_);
    const std::string frames_topic = t.cloud.empty() ? t.depth : t.cloud;
    std::set<std::string> wanted{frames_topic};
    for (const std::string& topic : {t.colour, t.pose, t.info, t.colour_info, std::string("/tf"), std::string("/tf_static")}) {
      if (!topic.empty() && topics.count(topic)) wanted.insert(topic);
    }
    bag::Gathered g;
    if (!t.pose.empty()) g.track.emplace();
    const std::string name = file_.string();
    store_->forEach(&wanted, [&](const Incoming& m) {
      requireCdr(m, file_);
      const std::string source = name + ": " + m.topic;
      const std::string type = ros1Type(m.type);
      if (m.topic == frames_topic || m.topic == t.colour) {
        const cdr::Header h = cdr::header(m.data, source);
        (m.topic == frames_topic ? g.depths : g.colours).push_back({h.stamp, m.handle, bag::frameName(h.frame_id)});
      } else if (m.topic == t.pose) {
        if (type == bag::kOdometry) {
          const cdr::Transform p = cdr::odometry(m.data, source);
          g.track->child_frame = bag::frameName(p.child);
          g.track->poses.push_back({p.header.stamp, transformOf(p, source)});
        } else {
          const cdr::Transform p = cdr::poseStamped(m.data, source);
          g.track->poses.push_back({p.header.stamp, transformOf(p, source)});
        }
      } else if (m.topic == "/tf" || m.topic == "/tf_static") {
        if (type != bag::kTfMessage) {
          throw DataError(source + " is a " + m.type + ", not tf2_msgs/msg/TFMessage");
        }
        for (const cdr::Transform& tr : cdr::tfMessage(m.data, source)) {
          std::string context = source;
          context.append(" ").append(tr.header.frame_id).append(" -> ").append(tr.child);
          g.tree.add(bag::frameName(tr.header.frame_id), bag::frameName(tr.child), tr.header.stamp,
                     transformOf(tr, context), m.topic == "/tf_static", context);
        }
      }
      if (m.topic == t.info && !g.k && !s.intrinsics) {
        const cdr::CameraInfo info = cdr::cameraInfo(m.data, source);
        g.k = bag::intrinsicsOf(info.k, source);
        g.info_width = info.width;
        g.info_height = info.height;
        g.info_topic = t.info;
      }
      if (m.topic == t.colour_info && !g.colour_k) {
        g.colour_k = bag::intrinsicsOf(cdr::cameraInfo(m.data, source).k, source);
      }
    });
    noteWhatWasLost(store_->note());
    assemble(t, s, std::move(g));
  }

 protected:
  bag::ImageMessage image(uint64_t message, bool compressed) const override {
    auto bytes = store_->message(message);
    const std::string source = file_.string() + ": message " + std::to_string(message);
    if (compressed) return {{}, cdr::compressedImage(bytes.data, source).view, bytes.owner};
    return {cdr::image(bytes.data, source).view, std::nullopt, bytes.owner};
  }
  bag::CloudMessage cloud(uint64_t message) const override {
    auto bytes = store_->message(message);
    auto c = cdr::cloud(bytes.data, file_.string() + ": message " + std::to_string(message));
    return {std::move(c.view), bytes.owner};
  }

 private:
  fs::path file_;
  std::unique_ptr<MessageStore> store_;
};

}  // namespace

bool isRos2Bag(const fs::path& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) return fs::exists(path / "metadata.yaml", ec);
  if (!fs::is_regular_file(path, ec)) return path.extension() == ".mcap" || path.extension() == ".db3";
  return storageOfFile(path).has_value();
}

std::unique_ptr<Dataset> openRos2Bag(const fs::path& path, const DatasetSettings& settings) {
  return std::make_unique<Ros2BagDataset>(path, settings);
}

std::vector<BagTopic> listRos2Bag(const fs::path& path, std::string* note) {
  const std::vector<fs::path> files = storageFiles(path);
  const fs::path file = bagName(path, files);
  const auto store = openStore(files);
  std::map<std::string, std::string> ros2_types;
  const bag::TopicMap topics = topicMap(*store, file, &ros2_types);
  std::vector<BagTopic> out;
  for (const auto& [name, info] : topics) out.push_back({name, ros2_types[name], info.messages, info.encoding});
  if (note) *note = store->note();
  return out;
}

std::vector<BagTopic> listBag(const fs::path& path, std::string* note) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw UsageError(path.string() + ": no such file or folder");
  if (note) note->clear();
  return isRos2Bag(path) ? listRos2Bag(path, note) : listRosBag1(path);
}

}  // namespace chronomap
