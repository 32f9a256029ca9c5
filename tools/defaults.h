#pragma once

// Every options struct's defaults as the code defines them, read from
// default-constructed structs, so that the docs can quote them without
// drifting: `flysfm defaults` prints them as docs/defaults.md, and the docs
// quote one as a code span followed by an HTML comment naming its key
// (`VALUE` then <!-- default KEY -->), which tests/tools/defaults_test.cc
// checks against the code.

#include <string>
#include <vector>

namespace flysfm {

// KEY is root '.' member path, following the C++ member names
// (engine.ba_tree.top_n). VALUE: bools true/false, integers in decimal,
// doubles as "%.10g", strings verbatim ("" when empty), enums by a readable
// name, lists joined by ", " ("none" when empty), callbacks "none" or "set".
struct OptionDefault {
  std::string key, value, help;
};

// Roots in this order: engine, checkpoint, camfi, camfi_emulator, watch,
// merged_source, view, retrieval_training, synthetic_capture; within a
// root, members in declaration order.
std::vector<OptionDefault> ListOptionDefaults();

// The Markdown page docs/defaults.md: one table per root.
std::string RenderOptionDefaults(const std::vector<OptionDefault>& defaults);

// A quoted default in a Markdown text: `value` <!-- default key -->. A
// comment not preceded by a code span on its line has an empty value and
// `has_value` false.
struct DefaultMarker {
  int line = 0;  // 1-based
  std::string key;
  std::string value;
  bool has_value = false;
};
std::vector<DefaultMarker> FindDefaultMarkers(const std::string& text);

// One message per bad marker of `text`, "file:line: what is wrong": an
// unknown key, a value other than the default, a comment without its code
// span. Empty when every marker quotes its default.
std::vector<std::string> CheckDefaultMarkers(const std::string& text, const std::string& file,
                                             const std::vector<OptionDefault>& defaults);

}  // namespace flysfm
