// `flysfm live --camfi HOST[:PORT] --out DIR` and `flysfm live --watch DIR
// --out DIR`: images reach the engine while they are being shot. SIGINT or
// SIGTERM ends the run cleanly (what was received is processed, the outputs
// are written whole); a second signal quits at once. A run restarted on the
// same --out after a crash first re-feeds the CAMFI shots already in
// DIR/images, or the watched files listed in DIR/watched.tsv, skipping
// those the checkpointed model in DIR/state holds already (docs/live.md).

#include <pthread.h>
#include <signal.h>

#include <cstdio>
#include <functional>
#include <iostream>
#include <mutex>
#include <thread>

#include "io/camfi/camfi_client.h"
#include "io/run/output_lock.h"
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

}  // namespace

void AddLiveCommand(CLI::App& app) {
  struct Flags {
    std::string camfi;
    std::string watch;
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
              "(or `flysfm camfi-emulator`) or from a folder something else writes into");
  CLI::Option* camfi =
      command->add_option("--camfi", flags->camfi,
                          "CAMFI transmitter HOST[:HTTP_PORT] (AP-mode default address "
                          "192.168.9.67, HTTP port 80); shots are stored in OUT/images");
  CLI::Option* watch = command->add_option(
      "--watch", flags->watch,
      "Folder to watch (FTP upload folder, phone app, card reader); each complete image "
      "is processed once, in the order files appear");
  camfi->excludes(watch);
  AddEngineFlags(command, &flags->engine);
  CamfiOptions& c = flags->camfi_options;
  command->add_option("--camfi-events-port", c.event_port,
                      "CAMFI event (Socket.IO) port")->capture_default_str();
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
      if (flags->camfi.empty() == flags->watch.empty()) {
        throw std::invalid_argument("give exactly one of --camfi HOST[:PORT] and --watch DIR");
      }
      const OutputLock lock(flags->engine.out);
      // Before anything (the engine's thread pools included) starts a thread.
      StartSignalThread();
      Engine engine = flags->engine.MakeEngine();
      std::unique_ptr<ImageSource> source;
      CamfiSource* camfi_source = nullptr;
      if (!flags->camfi.empty()) {
        CamfiOptions options = flags->camfi_options;
        options.tether_on_connect = !flags->no_tether;
        const std::size_t colon = flags->camfi.rfind(':');
        options.host = flags->camfi.substr(0, colon);
        if (colon != std::string::npos) {
          try {
            options.http_port = std::stoi(flags->camfi.substr(colon + 1));
          } catch (const std::exception&) {
            throw std::invalid_argument("--camfi " + flags->camfi + ": bad port");
          }
        }
        auto camfi = std::make_unique<CamfiSource>(
            options, std::filesystem::path(flags->engine.out) / "images");
        camfi_source = camfi.get();
        std::printf("live: CAMFI at %s (HTTP %d, events %d); shots stored in %s/images; "
                    "Ctrl-C to stop\n", options.host.c_str(), options.http_port,
                    options.event_port, flags->engine.out.c_str());
        source = std::move(camfi);
      } else {
        WatchedFolderOptions options = flags->watch_options;
        options.state_file = std::filesystem::path(flags->engine.out) / "watched.tsv";
        source = std::make_unique<WatchedFolderSource>(flags->watch, options);
        std::printf("live: watching %s%s; Ctrl-C to stop\n", flags->watch.c_str(),
                    options.recursive ? " and its sub-folders" : "");
      }
      std::fflush(stdout);
      SetStop([source = source.get()] { source->Stop(); });
      LimitedSource limited(source.get(), flags->max_images > 0 ? flags->max_images : -1);
      CommandRun run;
      run.live = true;
      exit_code = RunFromFlags(&limited, &engine, flags->engine, run);
      SetStop(nullptr);
      if (camfi_source != nullptr) {
        const CamfiStats stats = camfi_source->stats();
        std::printf("camfi: %d stored, %d replayed from the journal; %d events (%d duplicate), "
                    "%d found by listing; %d rejected downloads; %d sessions, %d ended by "
                    "errors\n",
                    stats.stored, stats.replayed, stats.events, stats.duplicate_events,
                    stats.found_by_listing, stats.download_failures, stats.sessions,
                    stats.session_failures);
        std::printf("camfi: %d re-fetched to compare, %d new shots at a known path; %d failed "
                    "and %d truncated listings; %d oversized bodies, %d timed-out downloads, "
                    "%d rejected event packets; %d store failures (disk full?); journal: %d "
                    "records skipped, %d torn\n",
                    stats.rechecked, stats.reused_paths, stats.listing_failures,
                    stats.truncated_listings, stats.oversized, stats.timed_out_downloads,
                    stats.rejected_packets, stats.store_failures, stats.journal_skipped,
                    stats.journal_torn);
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
