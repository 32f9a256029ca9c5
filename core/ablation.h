#pragma once

// The paper's components that can be switched off, each to measure what it
// brings: one list for the `batch`/`live`/`demo` flags, bench_engine
// --ablation and the engine test that runs every switch.

#include <vector>

#include "core/engine.h"

namespace flysfm {

struct EngineAblation {
  const char* name;  // as printed in the ablation table
  const char* flag;  // the command-line flag that applies it
  const char* help;
  void (*apply)(Engine::Options* options);
};

const std::vector<EngineAblation>& EngineAblations();

}  // namespace flysfm
