#pragma once

// The card listing, GET /files/<start>/<count> (docs/camfi.md 2.1): a
// JSON array of device paths, in an undocumented order, possibly fewer than
// asked for. A device may page by less than `count`, or ignore `start` and
// answer the same page every time, so the listing ends on what the pages
// bring, not on their length.

#include <cstddef>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace flysfm {

// The paths of one /files page, or nullopt with `*problem` set when the body
// is not a JSON array of strings (a busy camera's error page, a truncated
// body, nesting deeper than `max_json_depth`).
std::optional<std::vector<std::string>> ParseFilesPage(const std::string& body, int max_json_depth,
                                                       std::string* problem);

// One listing, page by page: the next page starts after the paths received
// so far, and the listing is over after an empty page, after a page that
// brings no path not already seen (a device that ignores `start`), or after
// `max_pages` pages (then `truncated()`).
class FilesListing {
 public:
  explicit FilesListing(int max_pages) : max_pages_(max_pages) {}

  std::size_t next_start() const { return next_start_; }
  // Adds one page; false once the listing is over.
  bool Add(const std::vector<std::string>& page);
  bool truncated() const { return truncated_; }
  // Every path seen, once each, in the order first seen.
  const std::vector<std::string>& paths() const { return paths_; }

 private:
  int max_pages_;
  int pages_ = 0;
  std::size_t next_start_ = 0;
  bool truncated_ = false;
  std::vector<std::string> paths_;
  std::set<std::string> seen_;
};

}  // namespace flysfm
