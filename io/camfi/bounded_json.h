#pragma once

// JSON from the device (listings, Engine.IO / Socket.IO payloads, error
// bodies) is parsed only after a bound on its nesting: nlohmann's parser is
// iterative, but the value it builds is destroyed recursively, so a body of a
// million "[" would end the process on a stack overflow, not in a message.

#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace flysfm {

// Deeper than any CAMFI payload (a listing is depth 1, an event 2 or 3) and
// far below what the stack holds.
constexpr int kDefaultMaxJsonDepth = 64;

// The value, or nullopt with `*problem` saying why ("not JSON", "nested
// deeper than N"). Depth counts open arrays and objects: "[]" is 1.
std::optional<nlohmann::json> ParseBoundedJson(std::string_view text, int max_depth,
                                               std::string* problem);

}  // namespace flysfm
