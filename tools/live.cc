// `flysfm live --camfi HOST[:PORT] --out DIR` and `flysfm live --watch DIR
// --out DIR`: images reach the engine while they are being shot. SIGINT or
// SIGTERM ends the run cleanly (what was received is processed, the outputs
// are written whole); a second signal quits at once. A run restarted on the
// same --out after a crash first re-feeds the CAMFI shots already in
// DIR/images, or the watched files listed in DIR/watched.tsv, skipping
// those the checkpointed model in DIR/state holds already (docs/live.md).
// Several --camfi and --watch (one per photographer) feed one model through
// a MergedSource, each source with its store or state file in
// DIR/sources/<tag>/.

#include <pthread.h>
#include <signal.h>

#include <cstdio>
#include <functional>
#include <iostream>
#include <memory>
#include <mutex>
#include <set>
#include <thread>

#include "io/camfi/camfi_client.h"
#include "io/run/output_lock.h"
#include "io/sources/merged_source.h"
#include "io/sources/watched_folder.h"
#include "tools/commands.h"
#include "tools/engine_flags.h"

namespace flysfm {
namespace {

// What the signal thread calls; cleared before the source it stops is gone.
std::mutex stop_mutex;
std::function<void()> stop_source;

void SetStop(std::function<void()> stop) {
  std::lock_guard<std::mutex> lock(stop_mutex);
  stop_source = std::move(stop);
}

// Signals are taken by one thread (sigwait) rather than a handler, so that
// stopping may lock and notify. Called before any other thread exists, so
// that every thread inherits the blocked mask.
void StartSignalThread() {
  static sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  std::thread([] {
    int signal = 0;
    sigwait(&signals, &signal);
    std::fprintf(stderr, "\nstopping: finishing the images received (again to quit at once)\n");
    {
      std::lock_guard<std::mutex> lock(stop_mutex);
      if (stop_source) stop_source();
    }
    sigwait(&signals, &signal);
    std::_Exit(130);
  }).detach();
}

// One photographer's source.
struct LiveInput {
  std::string tag;
  std::unique_ptr<ImageSource> source;
  CamfiSource* camfi = nullptr;  // the source, when it is a CAMFI one
};

void PrintCamfiStats(const std::string& label, const CamfiStats& stats) {
  std::printf("%s: %d stored, %d replayed from the journal; %d events (%d duplicate), "
              "%d found by listing; %d rejected downloads; %d sessions, %d ended by "
              "errors\n",
              label.c_str(), stats.stored, stats.replayed, stats.events, stats.duplicate_events,
              stats.found_by_listing, stats.download_failures, stats.sessions,
              stats.session_failures);
  std::printf("%s: %d re-fetched to compare, %d new shots at a known path; %d failed "
              "and %d truncated listings; %d oversized bodies, %d timed-out downloads, "
              "%d rejected event packets; %d store failures (disk full?); journal: %d "
              "records skipped, %d torn\n",
              label.c_str(), stats.rechecked, stats.reused_paths, stats.listing_failures,
              stats.truncated_listings, stats.oversized, stats.timed_out_downloads,
              stats.rejected_packets, stats.store_failures, stats.journal_skipped,
              stats.journal_torn);
}

}  // namespace

void AddLiveCommand(CLI::App& app) {
  struct Flags {
    std::vector<std::string> camfi;
    std::vector<std::string> watch;
    std::vector<int> event_ports;
    CamfiOptions camfi_options;
    WatchedFolderOptions watch_options;
    EngineFlags engine;
    bool no_tether = false;
    int max_images = 0;
  };
  auto flags = std::make_shared<Flags>();
  // After every image: the model in --out is always the latest.
  flags->engine.refresh_seconds = 0;
  // A restart continues the model it left (a crash, Ctrl-C, another day).
  flags->engine.resume = true;
  CLI::App* command = app.add_subcommand(
      "live", "Process images while they are being shot: from a CAMFI WiFi transmitter "
              "(or `flysfm camfi-emulator`) or from a folder something else writes into; "
              "several of either, one per photographer, feed one model");
  command->add_option("--camfi", flags->camfi,
                      "CAMFI transmitter HOST[:HTTP_PORT] (AP-mode default address "
                      "192.168.9.67, HTTP port 80); shots are stored in OUT/images. Again "
                      "for another photographer's: each source's store is then "
                      "OUT/sources/camfi-HOST/images and its images are named camfi-HOST/...")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  command->add_option("--watch", flags->watch,
                      "Folder to watch (FTP upload folder, phone app, card reader); each "
                      "complete image is processed once, in the order files appear. Again "
                      "for another photographer's: each folder's state is then "
                      "OUT/sources/TAG/watched.tsv (TAG: its base name) and its images are "
                      "named TAG/...")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  AddEngineFlags(command, &flags->engine);
  CamfiOptions& c = flags->camfi_options;
  command->add_option("--camfi-events-port", flags->event_ports,
                      "CAMFI event (Socket.IO) port (default 8080): once for every --camfi, "
                      "or once per --camfi in their order")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  command->add_option("--camfi-password", c.password,
                      "CAMFI access password (HTTP authentication as user CamFi); "
                      "default: none");
  command->add_flag("--camfi-no-tether", flags->no_tether,
                    "Do not POST /tether/start on connect (then only remotely "
                    "triggered shots are announced)");
  command->add_flag("--camfi-fetch-existing", c.fetch_existing,
                    "Also fetch the files already on the card when the store is new "
                    "(default: off, they are ignored)")
      ->capture_default_str();
  command->add_option("--camfi-reconcile-seconds", c.reconcile_seconds,
                      "List the card this often to find shots whose event was missed")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_option("--camfi-engine-io", c.engine_io_version,
                      "Engine.IO protocol of the event channel: 3 (socket.io 1.x/2.x, "
                      "CAMFI as known) or 4 (newer firmware, if any)")
      ->check(CLI::IsMember({3, 4}))
      ->capture_default_str();
  command->add_option("--camfi-ping-interval-ms", c.ping_interval_override_ms,
                      "Override the device's Engine.IO pingInterval (0: the device's)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_option("--camfi-ping-timeout-ms", c.ping_timeout_override_ms,
                      "Override the device's Engine.IO pingTimeout (0: the device's)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_option("--camfi-retries", c.retries,
                      "Download attempts per shot before waiting for the next listing")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_option("--camfi-download-idle-seconds", c.download_idle_seconds,
                      "Abandon a download that receives nothing for this long")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_option("--watch-stable-seconds", flags->watch_options.stable_seconds,
                      "A watched file must keep its size this long before it is read")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_option("--watch-give-up-seconds", flags->watch_options.give_up_seconds,
                      "Report a watched file still incomplete after this long")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_option("--watch-recursive", flags->watch_options.recursive,
                      "Also watch the sub-folders, at any depth (a card's 100CANON then "
                      "101CANON, an FTP upload's dated folders); symbolic links to folders "
                      "and hidden entries are not followed")
      ->capture_default_str();
  command->add_option("--max-images", flags->max_images,
                      "Stop after this many images (0: run until Ctrl-C)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->callback([flags]() {
    int exit_code = 0;
    try {
      if (flags->camfi.empty() && flags->watch.empty()) {
        throw std::invalid_argument("give --camfi HOST[:PORT] or --watch DIR (each as often "
                                    "as there are photographers)");
      }
      if (!flags->event_ports.empty() && flags->event_ports.size() != 1 &&
          flags->event_ports.size() != flags->camfi.size()) {
        throw std::invalid_argument("give --camfi-events-port once, or once per --camfi");
      }
      const OutputLock lock(flags->engine.out);
      // Before anything (the engine's thread pools included) starts a thread.
      StartSignalThread();
      Engine engine = flags->engine.MakeEngine();
      const std::filesystem::path out(flags->engine.out);
      // CAMFI sources first, then watched folders, each in the order given:
      // the same command gives the same tags, which a restart finds its
      // stores and images by.
      std::vector<std::string> tags;
      std::set<std::string> given;
      for (const std::string& camfi : flags->camfi) {
        if (!given.insert("camfi " + camfi).second) {
          throw std::invalid_argument("--camfi " + camfi + " is given twice");
        }
        tags.push_back(SourceTagOfCamfi(camfi.substr(0, camfi.rfind(':'))));
      }
      for (const std::string& watch : flags->watch) {
        if (!given.insert("watch " + std::filesystem::weakly_canonical(watch).string()).second) {
          throw std::invalid_argument("--watch " + watch + " is given twice");
        }
        tags.push_back(SourceTagOfFolder(watch));
      }
      tags = UniqueSourceTags(tags);
      const bool several = tags.size() > 1;
      // One source keeps the layout of a single-source run: OUT/images,
      // OUT/watched.tsv. Several: each its own folder, by tag.
      const auto folder_of = [&](const std::string& tag) {
        return several ? out / "sources" / tag : out;
      };
      std::vector<LiveInput> inputs;
      for (std::size_t i = 0; i < flags->camfi.size(); ++i) {
        const std::string& camfi = flags->camfi[i];
        CamfiOptions options = flags->camfi_options;
        options.tether_on_connect = !flags->no_tether;
        if (!flags->event_ports.empty()) {
          options.event_port = flags->event_ports[flags->event_ports.size() == 1 ? 0 : i];
        }
        const std::size_t colon = camfi.rfind(':');
        options.host = camfi.substr(0, colon);
        if (colon != std::string::npos) {
          try {
            options.http_port = std::stoi(camfi.substr(colon + 1));
          } catch (const std::exception&) {
            throw std::invalid_argument("--camfi " + camfi + ": bad port");
          }
        }
        LiveInput input;
        input.tag = tags[inputs.size()];
        const std::filesystem::path store = folder_of(input.tag) / "images";
        auto source = std::make_unique<CamfiSource>(options, store);
        input.camfi = source.get();
        input.source = std::move(source);
        std::printf("live: %s%sCAMFI at %s (HTTP %d, events %d); shots stored in %s; "
                    "Ctrl-C to stop\n", several ? input.tag.c_str() : "", several ? ": " : "",
                    options.host.c_str(), options.http_port, options.event_port,
                    store.c_str());
        inputs.push_back(std::move(input));
      }
      for (const std::string& watch : flags->watch) {
        WatchedFolderOptions options = flags->watch_options;
        LiveInput input;
        input.tag = tags[inputs.size()];
        std::filesystem::create_directories(folder_of(input.tag));
        options.state_file = folder_of(input.tag) / "watched.tsv";
        input.source = std::make_unique<WatchedFolderSource>(watch, options);
        std::printf("live: %s%swatching %s%s; Ctrl-C to stop\n",
                    several ? input.tag.c_str() : "", several ? ": " : "", watch.c_str(),
                    options.recursive ? " and its sub-folders" : "");
        inputs.push_back(std::move(input));
      }
      std::fflush(stdout);
      std::unique_ptr<MergedSource> merged;
      ImageSource* source = inputs.front().source.get();
      CommandRun run;
      run.live = true;
      if (several) {
        std::vector<MergedSource::Input> merged_inputs;
        for (const LiveInput& input : inputs) merged_inputs.push_back({input.tag, input.source.get()});
        merged = std::make_unique<MergedSource>(std::move(merged_inputs));
        source = merged.get();
        run.sources = tags;
      }
      SetStop([source] { source->Stop(); });
      LimitedSource limited(source, flags->max_images > 0 ? flags->max_images : -1);
      exit_code = RunFromFlags(&limited, &engine, flags->engine, run);
      SetStop(nullptr);
      for (const LiveInput& input : inputs) {
        if (input.camfi != nullptr) {
          PrintCamfiStats(several ? "camfi " + input.tag : "camfi", input.camfi->stats());
        }
      }
    } catch (const std::invalid_argument& e) {
      std::cerr << "flysfm live: " << e.what() << "\n";
      exit_code = 2;
    } catch (const std::exception& e) {
      std::cerr << "flysfm live: " << e.what() << "\n";
      exit_code = 1;
    }
    SetStop(nullptr);
    if (exit_code != 0) throw CLI::RuntimeError(exit_code);
  });
}

}  // namespace flysfm
