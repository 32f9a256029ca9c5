#pragma once

// Several photographers feeding one model: one source per photographer (a
// folder, a watched folder, a CAMFI transmitter), merged into one stream of
// frames for the run loop. Each input has a tag, a short name unique in the
// run; with more than one input a frame is named `<tag>/<name>` (two
// photographers' IMG_0001.JPG stay two images) and carries its tag in
// Frame::source. Live inputs block in Next() until a shot arrives, so each
// input is read by a thread of its own into a bounded queue: a silent
// photographer holds up nobody, and a fast one cannot fill memory.

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "io/sources/image_source.h"

namespace flysfm {

// A tag for a folder's photographer: the folder's base name ("A/" gives "A"),
// its characters other than letters, digits, '.', '_' and '-' replaced by
// '_' (a tag names a folder under the output folder and prefixes image
// names); "source" when nothing is left.
std::string SourceTagOfFolder(const std::filesystem::path& folder);
// `camfi-HOST`, HOST cleaned as above.
std::string SourceTagOfCamfi(const std::string& host);
// The tags made unique in order: a tag already taken gets "-2", "-3", ...
// (the first keeps its own), so the same inputs in the same order always
// get the same tags: what a restart matches its stores and images by.
std::vector<std::string> UniqueSourceTags(const std::vector<std::string>& tags);

struct MergedSourceOptions {
  // In which order frames are handed on.
  enum class Order {
    // As they arrive from any input: live capture, where the order of the
    // world is the only one.
    kArrival,
    // By each frame's Frame::timestamp as the input gives it (a capture
    // time): a merge of the inputs' heads, so each input must hand its
    // frames in time order. Ties go to the input given first.
    kCaptureTime,
    // One frame of each input in turn (the first input's first frame, the
    // second's, ...); an input that has ended is passed over.
    kRoundRobin,
  };
  Order order = Order::kArrival;
  // Frames read ahead per input before its reader waits for the run loop to
  // take one: bounds memory (a frame may hold a whole file's bytes) while a
  // fast photographer runs ahead of the engine.
  int queue_frames = 2;

  // Throws std::invalid_argument naming the bad option.
  void Check() const;
};

class MergedSource : public ImageSource {
 public:
  struct Input {
    std::string tag;       // unique among the inputs (UniqueSourceTags)
    ImageSource* source;   // not owned; must outlive the MergedSource
  };

  // Starts one reader thread per input. Throws std::invalid_argument for
  // bad options, no input, or tags that are empty or not unique.
  MergedSource(std::vector<Input> inputs, const MergedSourceOptions& options = {});
  // Stops every input and joins the readers; a frame a reader holds that
  // nobody took is dropped with the run that ended.
  ~MergedSource() override;
  MergedSource(const MergedSource&) = delete;
  MergedSource& operator=(const MergedSource&) = delete;

  // The next frame in the options' order; blocks until one is due; nullopt
  // once every input has ended. With more than one input the frame is named
  // `<tag>/<name>`, carries its tag in Frame::source, and its timestamp is
  // its place in the merged stream (0, 1, 2, ...): the inputs' own times
  // (indices, or clocks of different cameras) would make shots of two
  // photographers taken within 0.1 s look like one video's neighbouring
  // frames to the rolling-shutter model. A single input's frames pass as
  // they are. An input whose Next() throws is reported on stderr and ends
  // while the others go on; once they have all ended, Next() throws one
  // std::runtime_error naming every failed input (the run loop's "source
  // failed"), then returns nullopt.
  std::optional<Frame> Next() override;
  // Stops every input: what each hands on after its Stop() (a CAMFI store's
  // shots, a watched folder's replay) still comes through, then nullopt.
  // Thread-safe.
  void Stop() override;

  const std::vector<Input>& inputs() const { return inputs_; }
  // Frames handed on per input, in the inputs' order.
  std::vector<int> num_frames() const;

 private:
  struct Queued {
    Frame frame;
    std::uint64_t arrival_order = 0;  // across inputs, as the readers queued them
    std::uint64_t index = 0;          // within its input
  };
  struct Reader {
    std::deque<Queued> queue;
    std::uint64_t num_read = 0;
    int num_handed_on = 0;
    bool done = false;
    std::string error;  // what its source threw
  };

  void Read(std::size_t input);
  // The input whose head goes next, or nullopt when the order must wait
  // for an input that has neither a frame queued nor ended.
  std::optional<std::size_t> PickLocked() const;

  std::vector<Input> inputs_;
  MergedSourceOptions options_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<Reader> readers_;
  std::uint64_t next_arrival_order_ = 0;
  std::uint64_t num_handed_on_ = 0;
  std::size_t next_turn_ = 0;  // kRoundRobin: the input whose turn it is
  bool closing_ = false;       // the destructor: readers drop what they hold
  bool failure_reported_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace flysfm
