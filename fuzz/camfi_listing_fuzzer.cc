// /files pages as a device may answer them: no input may crash the page
// parser, and a listing fed the same page twice must end (a device that
// ignores `start`), with each path once.

#include <cstddef>
#include <cstdint>
#include <set>
#include <string>

#include "io/camfi/bounded_json.h"
#include "io/camfi/camfi_listing.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string body(reinterpret_cast<const char*>(data), size);
  std::string problem;
  const auto page = flysfm::ParseFilesPage(body, flysfm::kDefaultMaxJsonDepth, &problem);
  if (!page) {
    if (problem.empty()) __builtin_trap();
    return 0;
  }
  flysfm::FilesListing listing(1000);
  if (listing.Add(*page) && listing.Add(*page)) __builtin_trap();
  const std::set<std::string> unique(listing.paths().begin(), listing.paths().end());
  if (unique.size() != listing.paths().size() || listing.next_start() > 2 * page->size()) {
    __builtin_trap();
  }
  return 0;
}
