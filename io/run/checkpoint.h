#pragma once

// The engine's checkpoint in a run's output folder, OUT/state, so that a
// restart continues the same model instead of replaying every image
// (docs/live.md, "Crash and resume"):
//   images/<id>.bin   an image's record, written once after its AddImage
//   windows/<id>.bin  its LSM windows, once it keeps only those
//   retrieval/<v>.bin the retrieval model learnt from the session, version
//                     v, written when retraining made a new one
//   snapshot.bin      the rest of the engine's state, replaced atomically
// Every file is written whole or not at all (temporary, then rename). A
// snapshot names the images it holds, and every record and windows file it
// needs is written before it: after a crash the last snapshot is whole and
// consistent, and the images that came after it are fed again.
//
// Records and windows cost each image its own share. The snapshot grows
// with the model, so it is written only when the engine has worked, since
// the last one, at least 1 / max_snapshot_share times that one's cost:
// snapshots take at most that share of the run, and what a crash loses is
// the last few images' work, which the restart redoes.

#include <filesystem>
#include <set>

#include "core/engine.h"

namespace flysfm {

class Checkpointer {
 public:
  struct Options {
    // Share of the engine's time the snapshots may take.
    double max_snapshot_share = 0.05;

    bool Check() const { return max_snapshot_share > 0 && max_snapshot_share <= 1; }
  };

  struct Summary {
    int num_snapshots = 0;
    double records_ms = 0;    // image records and windows
    double snapshots_ms = 0;
    std::size_t bytes = 0;    // written in all
    double last_snapshot_ms = 0;
    std::size_t last_snapshot_bytes = 0;
  };

  // `dir`: OUT/state. Bad options: std::invalid_argument.
  Checkpointer(std::filesystem::path dir, const Options& options);

  // Whether `dir` holds a snapshot to resume from.
  bool Exists() const;
  // Restores the engine (made as the checkpointed one was, before any
  // image) from `dir`. Throws std::runtime_error naming the problem.
  void Restore(Engine* engine);
  // A new model: removes what `dir` held.
  void Clear();

  // After an engine call that spent `engine_ms`: writes the records of the
  // images it added and the windows kept since, and the snapshot when due
  // (`final`: always, e.g. after Engine::Finish). Throws
  // std::runtime_error when a file cannot be written; the next call writes
  // what is still missing.
  void Update(const Engine& engine, double engine_ms, bool final = false);

  const Summary& summary() const { return summary_; }
  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path ImageFile(const char* folder, image_t image_id) const;

  std::filesystem::path dir_;
  Options options_;
  Summary summary_;
  // The last image whose record is written; images whose windows are not
  // written yet (kept whole by LSM); the retrieval model version written.
  image_t last_recorded_ = 0;
  int retrieval_model_version_ = 0;
  std::set<image_t> awaiting_windows_;
  double engine_ms_since_snapshot_ = 0;
  // The folders exist: not asked of the file system at every image.
  bool folders_made_ = false;
  bool snapshot_due_ = false;
};

}  // namespace flysfm
