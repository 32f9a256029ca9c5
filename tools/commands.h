#pragma once

// Sub-commands of the flysfm program, one function per command, each in its
// own tools/<name>.cc. A function registers the command, its options with
// their defaults and its callback on `app`.

#include <CLI/CLI.hpp>

namespace flysfm {

// flysfm batch DIR --out OUT [--camera ...] [--shuffle SEED] [--interval S]
void AddBatchCommand(CLI::App& app);
// flysfm camfi-emulator --images DIR [--port-http P] [--port-events Q] ...
void AddCamfiEmulatorCommand(CLI::App& app);
// flysfm defaults (prints docs/defaults.md)
void AddDefaultsCommand(CLI::App& app);
// flysfm demo [--out DIR] [--views N]
void AddDemoCommand(CLI::App& app);
// flysfm eval --groundtruth GT --trajectory TRAJ
void AddEvalCommand(CLI::App& app);
// flysfm live (--camfi HOST[:PORT] | --watch DIR) --out DIR
void AddLiveCommand(CLI::App& app);
// flysfm view OUT [--port P] [--lan]
void AddViewCommand(CLI::App& app);
// flysfm train-retrieval --images DIR [DIR ...] --out FILE
void AddTrainRetrievalCommand(CLI::App& app);

}  // namespace flysfm
