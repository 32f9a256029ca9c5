#include "io/sources/merged_source.h"

#include <cstdio>
#include <set>
#include <stdexcept>

namespace flysfm {
namespace {

std::string CleanTag(const std::string& text) {
  std::string tag;
  for (const char c : text) {
    const bool plain = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                       (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-';
    tag.push_back(plain ? c : '_');
  }
  // "." and ".." would name no folder of their own under the output folder.
  if (tag.find_first_not_of('.') == std::string::npos) return "source";
  return tag;
}

}  // namespace

std::string SourceTagOfFolder(const std::filesystem::path& folder) {
  std::filesystem::path path = folder.lexically_normal();
  // "A/" normalises to "A/", whose file name is empty.
  if (!path.has_filename() && path.has_parent_path()) path = path.parent_path();
  return CleanTag(path.filename().string());
}

std::string SourceTagOfCamfi(const std::string& host) { return "camfi-" + CleanTag(host); }

std::vector<std::string> UniqueSourceTags(const std::vector<std::string>& tags) {
  std::set<std::string> taken;
  std::vector<std::string> unique;
  for (const std::string& tag : tags) {
    std::string candidate = tag;
    for (int n = 2; taken.count(candidate) > 0; ++n) candidate = tag + "-" + std::to_string(n);
    taken.insert(candidate);
    unique.push_back(candidate);
  }
  return unique;
}

void MergedSourceOptions::Check() const {
  if (queue_frames < 1) throw std::invalid_argument("queue_frames must be >= 1");
}

MergedSource::MergedSource(std::vector<Input> inputs, const MergedSourceOptions& options)
    : inputs_(std::move(inputs)), options_(options), readers_(inputs_.size()) {
  options_.Check();
  if (inputs_.empty()) throw std::invalid_argument("a merged source needs at least one input");
  std::set<std::string> tags;
  for (const Input& input : inputs_) {
    if (input.tag.empty()) throw std::invalid_argument("a merged source's input has no tag");
    if (input.source == nullptr) throw std::invalid_argument("input " + input.tag + " has no source");
    if (!tags.insert(input.tag).second) {
      throw std::invalid_argument("two merged inputs are tagged " + input.tag);
    }
  }
  for (std::size_t i = 0; i < inputs_.size(); ++i) threads_.emplace_back([this, i] { Read(i); });
}

MergedSource::~MergedSource() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    closing_ = true;
  }
  changed_.notify_all();
  for (const Input& input : inputs_) input.source->Stop();
  for (std::thread& thread : threads_) thread.join();
}

void MergedSource::Stop() {
  // Outside the lock: an input's Stop() may wait for its own threads.
  for (const Input& input : inputs_) input.source->Stop();
}

void MergedSource::Read(std::size_t input) {
  Reader& reader = readers_[input];
  std::string error;
  while (true) {
    std::optional<Frame> frame;
    try {
      frame = inputs_[input].source->Next();
    } catch (const std::exception& e) {
      error = e.what();
    } catch (...) {
      error = "unknown exception";
    }
    if (!frame) break;
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [&] {
      return closing_ || reader.queue.size() < std::size_t(options_.queue_frames);
    });
    if (closing_) return;
    reader.queue.push_back({std::move(*frame), next_arrival_order_++, reader.num_read++});
    lock.unlock();
    changed_.notify_all();
  }
  if (!error.empty()) {
    std::fprintf(stderr, "source %s failed: %s; the other sources go on\n",
                 inputs_[input].tag.c_str(), error.c_str());
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    reader.done = true;
    reader.error = error;
  }
  changed_.notify_all();
}

std::optional<std::size_t> MergedSource::PickLocked() const {
  using Order = MergedSourceOptions::Order;
  std::optional<std::size_t> best;
  switch (options_.order) {
    case Order::kArrival:
      for (std::size_t i = 0; i < readers_.size(); ++i) {
        const std::deque<Queued>& queue = readers_[i].queue;
        if (queue.empty()) continue;
        if (!best || queue.front().arrival_order < readers_[*best].queue.front().arrival_order) {
          best = i;
        }
      }
      return best;
    case Order::kCaptureTime:
      // A merge of sorted streams: every input still going must show its
      // head before the earliest can be known.
      for (std::size_t i = 0; i < readers_.size(); ++i) {
        const std::deque<Queued>& queue = readers_[i].queue;
        if (queue.empty()) {
          if (!readers_[i].done) return std::nullopt;
          continue;
        }
        if (!best ||
            queue.front().frame.timestamp < readers_[*best].queue.front().frame.timestamp) {
          best = i;
        }
      }
      return best;
    case Order::kRoundRobin:
      // The first input from the one whose turn it is that has a frame,
      // passing over those that ended; one still going holds its turn.
      for (std::size_t k = 0; k < readers_.size(); ++k) {
        const std::size_t i = (next_turn_ + k) % readers_.size();
        if (!readers_[i].queue.empty()) return i;
        if (!readers_[i].done) return std::nullopt;
      }
      return std::nullopt;
  }
  return std::nullopt;
}

std::optional<Frame> MergedSource::Next() {
  std::unique_lock<std::mutex> lock(mutex_);
  std::optional<std::size_t> input;
  changed_.wait(lock, [&] {
    input = PickLocked();
    if (input) return true;
    for (const Reader& reader : readers_) {
      if (!reader.done || !reader.queue.empty()) return false;
    }
    return true;
  });
  if (!input) {
    if (failure_reported_) return std::nullopt;
    std::string failed;
    for (std::size_t i = 0; i < readers_.size(); ++i) {
      if (readers_[i].error.empty()) continue;
      failed += (failed.empty() ? "" : "; ") + inputs_[i].tag + ": " + readers_[i].error;
    }
    if (failed.empty()) return std::nullopt;
    failure_reported_ = true;
    throw std::runtime_error("source failed (" + failed + ")");
  }
  Reader& reader = readers_[*input];
  Frame frame = std::move(reader.queue.front().frame);
  reader.queue.pop_front();
  ++reader.num_handed_on;
  next_turn_ = (*input + 1) % readers_.size();
  if (inputs_.size() > 1) {
    frame.name = inputs_[*input].tag + "/" + frame.name;
    frame.source = inputs_[*input].tag;
    frame.timestamp = double(num_handed_on_);
  }
  ++num_handed_on_;
  lock.unlock();
  // A reader waiting for room in its queue.
  changed_.notify_all();
  return frame;
}

std::vector<int> MergedSource::num_frames() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<int> counts;
  for (const Reader& reader : readers_) counts.push_back(reader.num_handed_on);
  return counts;
}

}  // namespace flysfm
