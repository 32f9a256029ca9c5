#include "io/camfi/camfi_journal.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace flysfm {
namespace {

constexpr char kHex[] = "0123456789ABCDEF";

int HexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

std::vector<std::string_view> SplitTabs(std::string_view line) {
  std::vector<std::string_view> fields;
  while (true) {
    const std::size_t tab = line.find('\t');
    fields.push_back(line.substr(0, tab));
    if (tab == std::string_view::npos) return fields;
    line.remove_prefix(tab + 1);
  }
}

std::optional<std::uint64_t> ParseCount(std::string_view text) {
  std::uint64_t value = 0;
  const char* end = text.data() + text.size();
  const auto [stop, error] = std::from_chars(text.data(), end, value);
  if (text.empty() || error != std::errc() || stop != end) return std::nullopt;
  return value;
}

bool IsSha1(std::string_view text) {
  if (text.size() != 40) return false;
  for (const char c : text) {
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  }
  return true;
}

// A store name is joined to the store folder: it must stay inside it.
bool IsFileName(const std::string& name) {
  return !name.empty() && name != "." && name != ".." && name.find('/') == std::string::npos &&
         name.find('\0') == std::string::npos;
}

// The record on `line`, or nullopt with `*why`.
std::optional<JournalRecord> ParseRecord(std::string_view line, std::string* why) {
  const std::vector<std::string_view> raw = SplitTabs(line);
  std::vector<std::string> fields;
  for (const std::string_view field : raw) {
    std::optional<std::string> value = UnescapeJournalField(field);
    if (!value) {
      *why = "bad escape";
      return std::nullopt;
    }
    fields.push_back(std::move(*value));
  }
  JournalRecord record;
  if (fields[0] == "baseline" && fields.size() == 1) {
    record.kind = JournalRecord::Kind::kBaseline;
    return record;
  }
  if (fields[0] == "ignored" && fields.size() == 2 && !fields[1].empty()) {
    record.kind = JournalRecord::Kind::kIgnored;
    record.device_path = fields[1];
    return record;
  }
  if (fields[0] == "stored" && (fields.size() == 4 || fields.size() == 5)) {
    record.kind = JournalRecord::Kind::kStored;
    record.device_path = fields[1];
    record.store_name = fields[2];
    const std::optional<std::uint64_t> bytes = ParseCount(fields[3]);
    if (record.device_path.empty() || !IsFileName(record.store_name) || !bytes) {
      *why = "bad stored record";
      return std::nullopt;
    }
    record.bytes = *bytes;
    if (fields.size() == 5) {
      if (!IsSha1(fields[4])) {
        *why = "bad hash";
        return std::nullopt;
      }
      record.sha1 = fields[4];
    }
    return record;
  }
  *why = "unknown record";
  return std::nullopt;
}

}  // namespace

std::string EscapeJournalField(std::string_view field) {
  std::string escaped;
  escaped.reserve(field.size());
  for (const char c : field) {
    if (c == '\t' || c == '\n' || c == '\r' || c == '%' || c == '\\') {
      const auto byte = static_cast<unsigned char>(c);
      escaped.push_back('%');
      escaped.push_back(kHex[byte >> 4]);
      escaped.push_back(kHex[byte & 0xF]);
    } else {
      escaped.push_back(c);
    }
  }
  return escaped;
}

std::optional<std::string> UnescapeJournalField(std::string_view field) {
  std::string text;
  text.reserve(field.size());
  for (std::size_t i = 0; i < field.size(); ++i) {
    if (field[i] != '%') {
      text.push_back(field[i]);
      continue;
    }
    if (i + 2 >= field.size()) return std::nullopt;
    const int high = HexValue(field[i + 1]);
    const int low = HexValue(field[i + 2]);
    if (high < 0 || low < 0) return std::nullopt;
    text.push_back(char(high * 16 + low));
    i += 2;
  }
  return text;
}

std::string FormatJournalRecord(const JournalRecord& record) {
  switch (record.kind) {
    case JournalRecord::Kind::kBaseline:
      return "baseline\n";
    case JournalRecord::Kind::kIgnored:
      return "ignored\t" + EscapeJournalField(record.device_path) + "\n";
    case JournalRecord::Kind::kStored:
      // A record without a hash (read from an older journal) stays one.
      return "stored\t" + EscapeJournalField(record.device_path) + "\t" +
             EscapeJournalField(record.store_name) + "\t" + std::to_string(record.bytes) +
             (record.sha1.empty() ? "" : "\t" + EscapeJournalField(record.sha1)) + "\n";
  }
  return "";
}

JournalContents ParseJournal(std::string_view text) {
  JournalContents contents;
  std::size_t start = 0;
  int number = 0;
  while (true) {
    const std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) break;
    ++number;
    std::string why;
    if (std::optional<JournalRecord> record = ParseRecord(text.substr(start, end - start), &why)) {
      contents.records.push_back(std::move(*record));
    } else {
      contents.skipped.push_back("line " + std::to_string(number) + ": " + why);
    }
    start = end + 1;
  }
  contents.complete_bytes = start;
  return contents;
}

CamfiJournalFile::CamfiJournalFile(const std::filesystem::path& path, WriteFault write_fault,
                         JournalContents* contents, std::size_t* torn_bytes)
    : path_(path), write_fault_(std::move(write_fault)) {
  std::string text;
  {
    std::ifstream in(path_, std::ios::binary);
    std::ostringstream buffer;
    buffer << in.rdbuf();
    text = buffer.str();
  }
  *contents = ParseJournal(text);
  *torn_bytes = text.size() - contents->complete_bytes;
  fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0 || (*torn_bytes > 0 && ::ftruncate(fd_, off_t(contents->complete_bytes)) != 0)) {
    const std::string reason = std::strerror(errno);
    if (fd_ >= 0) ::close(fd_);
    throw std::runtime_error("cannot write " + path_.string() + ": " + reason);
  }
  size_ = contents->complete_bytes;
}

CamfiJournalFile::~CamfiJournalFile() {
  if (fd_ >= 0) ::close(fd_);
}

bool CamfiJournalFile::Append(const std::string& records, std::string* error) {
  const int fault = write_fault_ ? write_fault_(path_) : 0;
  const std::size_t size = fault != 0 ? records.size() / 2 : records.size();
  std::size_t written = 0;
  int failure = fault;
  while (written < size) {
    const ssize_t n =
        ::pwrite(fd_, records.data() + written, size - written, off_t(size_ + written));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      failure = n < 0 ? errno : EIO;
      break;
    }
    written += std::size_t(n);
  }
  if (failure == 0) {
    size_ += written;
    return true;
  }
  *error = "cannot append to " + path_.string() + ": " + std::strerror(failure);
  // Half a record would glue the next one onto it.
  if (::ftruncate(fd_, off_t(size_)) != 0) {
    *error +=
        "; cutting the half-written record off failed too: " + std::string(std::strerror(errno));
  }
  return false;
}

}  // namespace flysfm
