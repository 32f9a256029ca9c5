// journal.tsv as a crash, a disk or a hand may leave it: no input may crash
// the reader, the complete part must end on a newline, and every record read
// must be written and read back the same, with any byte in its fields.

#include <cstddef>
#include <cstdint>
#include <string>

#include "io/camfi/camfi_journal.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const flysfm::JournalContents contents = flysfm::ParseJournal(text);
  if (contents.complete_bytes > size ||
      (contents.complete_bytes > 0 && text[contents.complete_bytes - 1] != '\n')) {
    __builtin_trap();
  }
  std::string written;
  for (const flysfm::JournalRecord& record : contents.records) {
    written += flysfm::FormatJournalRecord(record);
  }
  const flysfm::JournalContents again = flysfm::ParseJournal(written);
  if (!again.skipped.empty() || again.records.size() != contents.records.size()) {
    __builtin_trap();
  }
  for (std::size_t i = 0; i < again.records.size(); ++i) {
    const flysfm::JournalRecord& a = contents.records[i];
    const flysfm::JournalRecord& b = again.records[i];
    if (a.kind != b.kind || a.device_path != b.device_path || a.store_name != b.store_name ||
        a.bytes != b.bytes || a.sha1 != b.sha1) {
      __builtin_trap();
    }
  }
  if (flysfm::UnescapeJournalField(flysfm::EscapeJournalField(text)) != text) __builtin_trap();
  return 0;
}
