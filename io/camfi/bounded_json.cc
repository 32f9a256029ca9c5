#include "io/camfi/bounded_json.h"

#include <algorithm>

namespace flysfm {
namespace {

// The deepest nesting of arrays and objects, brackets inside strings not
// counted; stops counting once over `limit`.
int NestingDepth(std::string_view text, int limit) {
  int depth = 0;
  int deepest = 0;
  bool in_string = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\') {
        ++i;
      } else if (c == '"') {
        in_string = false;
      }
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      deepest = std::max(deepest, ++depth);
      if (deepest > limit) break;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return deepest;
}

}  // namespace

std::optional<nlohmann::json> ParseBoundedJson(std::string_view text, int max_depth,
                                               std::string* problem) {
  if (NestingDepth(text, max_depth) > max_depth) {
    *problem = "JSON nested deeper than " + std::to_string(max_depth);
    return std::nullopt;
  }
  nlohmann::json value = nlohmann::json::parse(text.begin(), text.end(), nullptr,
                                               /*allow_exceptions=*/false);
  if (value.is_discarded()) {
    *problem = "not JSON";
    return std::nullopt;
  }
  return value;
}

}  // namespace flysfm
