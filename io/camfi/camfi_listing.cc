#include "io/camfi/camfi_listing.h"

#include "io/camfi/bounded_json.h"

namespace flysfm {

std::optional<std::vector<std::string>> ParseFilesPage(const std::string& body, int max_json_depth,
                                                       std::string* problem) {
  const std::optional<nlohmann::json> list = ParseBoundedJson(body, max_json_depth, problem);
  if (!list) return std::nullopt;
  if (!list->is_array()) {
    *problem = "not a JSON array";
    return std::nullopt;
  }
  std::vector<std::string> paths;
  paths.reserve(list->size());
  for (const nlohmann::json& entry : *list) {
    if (!entry.is_string()) {
      *problem = "an entry of the array is not a string";
      return std::nullopt;
    }
    paths.push_back(entry.get<std::string>());
  }
  return paths;
}

bool FilesListing::Add(const std::vector<std::string>& page) {
  bool brought_new = false;
  for (const std::string& path : page) {
    if (seen_.insert(path).second) {
      paths_.push_back(path);
      brought_new = true;
    }
  }
  next_start_ += page.size();
  ++pages_;
  if (!brought_new) return false;
  if (pages_ >= max_pages_) {
    truncated_ = true;
    return false;
  }
  return true;
}

}  // namespace flysfm
