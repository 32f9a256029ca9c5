#pragma once

// Options shared by the commands that run the engine (batch, demo, live):
// the camera, the retrieval model, the ablation switches and the output.

#include <map>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "core/engine.h"
#include "io/run/run_writer.h"
#include "io/sources/image_source.h"

namespace flysfm {

struct EngineFlags {
  std::string camera;           // "MODEL p1,p2,..."; empty: unknown
  std::string retrieval_model;  // file from train-retrieval; empty: bootstrap
  // Per EngineAblations() flag, whether it was given.
  std::map<std::string, bool> ablations;
  bool no_global_ba = false;
  std::string out;
  double refresh_seconds = 2.0;

  // Throws std::invalid_argument with a one-line message for a bad camera or
  // an unreadable retrieval model.
  Engine MakeEngine() const;
};

void AddEngineFlags(CLI::App* command, EngineFlags* flags);

// Runs every frame of `source` through the engine, printing one line per
// image result and keeping `out` current; ends with Finish() and the final
// model. With `live`, each line also gives the delay from the image's arrival
// (Frame::arrival) to its result, and the run ends with the median delay.
// Returns the process exit code.
int RunEngine(ImageSource* source, Engine* engine, const EngineFlags& flags,
              bool live = false);

}  // namespace flysfm
