#pragma once

// The store's journal, journal.tsv: one record a line, tab-separated fields,
// appended (and flushed to the kernel) after the file it names is complete:
//   baseline                              the first listing of a fresh store is done
//   ignored <device path>                 on the card before the session began
//   stored <device path> <name> <bytes> <sha1>
// Fields are escaped: tab, newline, CR, '%' and '\' are written as %XX, so a
// device path can never split or inject a record. (Records written before
// the hash have four fields; they are read as they are.) Reading never stops
// on a bad line: a malformed record is skipped and reported, and a last line
// without its newline is a record a crash cut short (it is dropped).

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace flysfm {

struct JournalRecord {
  enum class Kind { kBaseline, kIgnored, kStored };
  Kind kind = Kind::kBaseline;
  std::string device_path;  // kIgnored, kStored
  std::string store_name;   // kStored: a file name in the store folder
  std::uint64_t bytes = 0;  // kStored
  std::string sha1;         // kStored: 40 lower-case hex digits; empty in old records

  static JournalRecord Baseline() { return {}; }
  static JournalRecord Ignored(std::string device_path) {
    JournalRecord record;
    record.kind = Kind::kIgnored;
    record.device_path = std::move(device_path);
    return record;
  }
  static JournalRecord Stored(std::string device_path, std::string store_name, std::uint64_t bytes,
                              std::string sha1) {
    JournalRecord record = Ignored(std::move(device_path));
    record.kind = Kind::kStored;
    record.store_name = std::move(store_name);
    record.bytes = bytes;
    record.sha1 = std::move(sha1);
    return record;
  }
};

std::string EscapeJournalField(std::string_view field);
// nullopt for a "%" not followed by two hex digits.
std::optional<std::string> UnescapeJournalField(std::string_view field);

// The record as one line, with its newline.
std::string FormatJournalRecord(const JournalRecord& record);

struct JournalContents {
  std::vector<JournalRecord> records;
  // One message per malformed line skipped: "line N: why".
  std::vector<std::string> skipped;
  // Bytes up to the end of the last complete line: less than the text when
  // its last line has no newline.
  std::size_t complete_bytes = 0;
};

JournalContents ParseJournal(std::string_view text);

// The journal file, open for appending. Every append is whole records or
// nothing: a write that fails half way (a full disk) is cut back off the
// file, and the next append works as soon as the disk does.
class CamfiJournalFile {
 public:
  // Tests only: asked before every write to the store with the file it
  // writes; an errno value (ENOSPC) makes the write put down half its bytes
  // and fail with it, as a full disk does; 0 lets it through.
  using WriteFault = std::function<int(const std::filesystem::path& file)>;

  // Reads `path` (missing: empty) into `*contents`, cuts a torn last line off
  // the file (`*torn_bytes`: how many bytes) and opens it for appending.
  // Throws std::runtime_error naming the path when that fails.
  CamfiJournalFile(const std::filesystem::path& path, WriteFault write_fault, JournalContents* contents,
              std::size_t* torn_bytes);
  ~CamfiJournalFile();
  CamfiJournalFile(const CamfiJournalFile&) = delete;
  CamfiJournalFile& operator=(const CamfiJournalFile&) = delete;

  // Appends `records` (formatted lines) in one write; false with `*error` when
  // it failed, the file then as it was before.
  bool Append(const std::string& records, std::string* error);

 private:
  std::filesystem::path path_;
  WriteFault write_fault_;
  int fd_ = -1;
  std::uint64_t size_ = 0;
};

}  // namespace flysfm
