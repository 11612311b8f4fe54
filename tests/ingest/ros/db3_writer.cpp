#include "db3_writer.h"

#include <sqlite3.h>

#include <memory>
#include <stdexcept>

#include "ingest/ros/mcap.h"

namespace chronomap::test {

namespace fs = std::filesystem;

void writeDb3(const fs::path& mcap_path, const fs::path& db3, const std::map<std::string, std::string>& formats) {
  fs::remove(db3);
  sqlite3* raw = nullptr;
  const int opened = sqlite3_open(db3.c_str(), &raw);
  const std::unique_ptr<sqlite3, int (*)(sqlite3*)> db(raw, sqlite3_close);
  if (opened != SQLITE_OK) throw std::runtime_error(db3.string() + ": cannot create");
  const auto fail = [&](const std::string& what) {
    throw std::runtime_error(db3.string() + ": " + what + ": " + sqlite3_errmsg(db.get()));
  };
  const auto exec = [&](const char* sql) {
    if (sqlite3_exec(db.get(), sql, nullptr, nullptr, nullptr) != SQLITE_OK) fail(sql);
  };
  exec("CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);"
       "INSERT INTO schema VALUES (4, 'iron');"
       "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, "
       "serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL, type_description_hash TEXT NOT NULL);"
       "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, timestamp INTEGER NOT NULL, "
       "data BLOB NOT NULL);"
       "CREATE INDEX timestamp_idx ON messages (timestamp ASC);"
       "BEGIN;");
  const auto prepare = [&](const char* sql) {
    sqlite3_stmt* st = nullptr;
    if (sqlite3_prepare_v2(db.get(), sql, -1, &st, nullptr) != SQLITE_OK) fail(sql);
    return std::unique_ptr<sqlite3_stmt, int (*)(sqlite3_stmt*)>(st, sqlite3_finalize);
  };
  const auto topic = prepare("INSERT INTO topics VALUES (?, ?, ?, ?, '', '')");
  const auto message = prepare("INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)");
  mcap::Reader reader(mcap_path);
  std::map<uint16_t, int> topic_ids;
  reader.forEachMessage([&](const mcap::Message& m) {
    auto it = topic_ids.find(m.channel);
    if (it == topic_ids.end()) {
      const mcap::Channel& ch = reader.channels().at(m.channel);
      const int id = static_cast<int>(topic_ids.size()) + 1;
      const std::string type = reader.schemas().at(ch.schema_id).name;
      const std::string format = formats.count(ch.topic) ? formats.at(ch.topic) : ch.message_encoding;
      sqlite3_bind_int(topic.get(), 1, id);
      sqlite3_bind_text(topic.get(), 2, ch.topic.c_str(), -1, SQLITE_TRANSIENT);
      sqlite3_bind_text(topic.get(), 3, type.c_str(), -1, SQLITE_TRANSIENT);
      sqlite3_bind_text(topic.get(), 4, format.c_str(), -1, SQLITE_TRANSIENT);
      if (sqlite3_step(topic.get()) != SQLITE_DONE) fail("insert topic " + ch.topic);
      sqlite3_reset(topic.get());
      it = topic_ids.emplace(m.channel, id).first;
    }
    sqlite3_bind_int(message.get(), 1, it->second);
    sqlite3_bind_int64(message.get(), 2, static_cast<sqlite3_int64>(m.log_time));
    sqlite3_bind_blob(message.get(), 3, m.data.data(), static_cast<int>(m.data.size()), SQLITE_TRANSIENT);
    if (sqlite3_step(message.get()) != SQLITE_DONE) fail("insert message");
    sqlite3_reset(message.get());
  });
  exec("COMMIT;");
}

}  // namespace chronomap::test
